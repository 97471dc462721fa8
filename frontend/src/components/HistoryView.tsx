/**
 * The history plot of the panel: one plot's fields over the recording (docs/api.md "History"),
 * from the moving window of the last 15 min … 7 days back into any range of the past by zoom,
 * pan, a custom range or a click on an event marker, and "Back to live". Ranges are fetched
 * decimated to the plot's width and drawn as min/max envelopes straight into Plotly (no sample
 * passes through React state); React holds only the window, the markers and the export links.
 */
import { memo, useEffect, useMemo, useRef, useState } from "react";
import { api } from "../lib/api";
import { historyFetcher } from "../lib/historyApi";
import { historyLink } from "../lib/historyLink";
import {
  DEFAULT_SPAN_S,
  EXPORT_FORMATS,
  RANGE_PRESETS,
  RangeLoader,
  axisTimeToEpochS,
  backToLive,
  bucketsForWidth,
  customWindow,
  envelopeTraces,
  exportUrl,
  fieldsOf,
  markersOf,
  presetOf,
  presetWindow,
  rangeOf,
  windowAfterMove,
  windowAround,
  type HistoryWindow,
  type Marker,
  type RangeData,
  type TimeRange,
} from "../lib/historyView";
import { plotlyBackend } from "../lib/plotlyAdapter";
import { ALL_PLOTS, axisTitles } from "../lib/plots";
import { DEFAULT_PLOT_HEIGHT_PX, plotMargin, type PlotTheme } from "../lib/plotting";
import "../styles/history.css";

const HEIGHT_PX = DEFAULT_PLOT_HEIGHT_PX + 40;

function localInput(time_s: number): string {
  const d = new Date(time_s * 1000 - new Date(time_s * 1000).getTimezoneOffset() * 60_000);
  return d.toISOString().slice(0, 19);
}

function localText(time_s: number): string {
  return new Date(time_s * 1000).toLocaleString();
}

interface Props {
  readonly robot: string;
  readonly theme: PlotTheme;
}

export const HistoryView = memo(function HistoryView({ robot, theme }: Props) {
  const [specId, setSpecId] = useState<string>(ALL_PLOTS[0]?.id ?? "");
  const spec = ALL_PLOTS.find((s) => s.id === specId) ?? ALL_PLOTS[0];
  const [window, setWindow] = useState<HistoryWindow>({ mode: "live", span_s: DEFAULT_SPAN_S });
  const [shown, setShown] = useState<TimeRange | null>(null);
  const [markers, setMarkers] = useState<readonly Marker[]>([]);
  const [error, setError] = useState<string | null>(null);
  const [custom, setCustom] = useState<{ from: string; to: string } | null>(null);
  const [customError, setCustomError] = useState<string | null>(null);
  const container = useRef<HTMLDivElement | null>(null);
  const twoAxes = spec?.series.some((s) => s.axis === "y2") ?? false;
  const margin = plotMargin(twoAxes);
  const titles = spec !== undefined ? axisTitles(spec) : { y: "", y2: null };
  const fields = spec !== undefined ? fieldsOf(spec) : "";

  // The plot and its loader, for one robot and plot choice.
  const loader = useMemo(() => {
    if (spec === undefined) return null;
    let drawn: TimeRange | null = null;
    let draws = 0;
    const dark = theme === "dark";
    const fg = dark ? "#d8dde3" : "#222";
    const grid = dark ? "#2f3740" : "#e3e3e3";
    const shift_ms = () => new Date().getTimezoneOffset() * 60_000;
    const draw = (data: RangeData) => {
      const el = container.current;
      if (el === null) return;
      const shift = shift_ms();
      const { range, answer } = data;
      const shapes = markersOf(data.events, range).map((m) => ({
        type: "line",
        xref: "x",
        yref: "paper",
        x0: m.time_s * 1000 - shift,
        x1: m.time_s * 1000 - shift,
        y0: 0,
        y1: 1,
        line: { color: m.kind === "alarm" ? "#D55E00" : "#888", width: 1, dash: "dot" },
      }));
      const layout: Record<string, unknown> = {
        uirevision: ++draws,
        autosize: true,
        height: HEIGHT_PX,
        margin,
        showlegend: false,
        paper_bgcolor: dark ? "#12161b" : "#ffffff",
        plot_bgcolor: dark ? "#12161b" : "#ffffff",
        font: { color: fg, size: 11 },
        hovermode: "x",
        shapes,
        xaxis: {
          type: "date",
          autorange: false,
          range: [range.from_s * 1000 - shift, range.to_s * 1000 - shift],
          gridcolor: grid,
        },
        yaxis: { autorange: true, gridcolor: grid, zeroline: false },
      };
      if (twoAxes) layout.yaxis2 = { autorange: true, overlaying: "y", side: "right", zeroline: false, showgrid: false };
      drawn = range;
      plotlyBackend.react(el, envelopeTraces(answer, spec, shift), layout, {
        responsive: true,
        displaylogo: false,
        modeBarButtonsToRemove: ["select2d", "lasso2d", "toImage"],
      });
      el.dataset.from = String(range.from_s);
      el.dataset.to = String(range.to_s);
      el.dataset.frames = String(answer.frames);
      el.dataset.mode = answer.mode;
      el.dataset.points = String(answer.t.length);
      setShown(range);
      setMarkers(markersOf(data.events, range));
      setError(null);
    };
    const rangeLoader = new RangeLoader(historyFetcher(api.client, robot, fields), draw, setError);
    const onMove = () => {
      const el = container.current;
      if (el === null) return;
      const x = plotlyBackend.zoomedAxes(el).xaxis;
      if (x === undefined) {
        // Autoscale (a double click): back to the moving window.
        setWindow((w) => backToLive(w));
        return;
      }
      const range = { from_s: axisTimeToEpochS(x[0], shift_ms()), to_s: axisTimeToEpochS(x[1], shift_ms()) };
      if (!Number.isFinite(range.from_s) || !Number.isFinite(range.to_s) || range.to_s <= range.from_s) return;
      // Our own drawing of a range is no move of the person's.
      const tolerance_s = (range.to_s - range.from_s) / 1000;
      if (drawn !== null && Math.abs(drawn.from_s - range.from_s) < tolerance_s && Math.abs(drawn.to_s - range.to_s) < tolerance_s) return;
      setWindow(windowAfterMove(range, Date.now() / 1000));
    };
    return { rangeLoader, onMove };
    // eslint-disable-next-line react-hooks/exhaustive-deps -- margin and twoAxes follow spec
  }, [robot, spec, theme, fields]);

  useEffect(() => {
    const el = container.current;
    if (el === null || loader === null) return;
    plotlyBackend.newPlot(el, [], { height: HEIGHT_PX, margin }, { responsive: true, displaylogo: false });
    plotlyBackend.onRelayout?.(el, loader.onMove);
    return () => {
      loader.rangeLoader.stop();
      plotlyBackend.purge(el);
    };
    // eslint-disable-next-line react-hooks/exhaustive-deps -- margin follows loader's spec
  }, [loader]);

  // Fetch the window's range: now (debounced while the view moves), and while live, again as
  // often as a new bucket fills (at least every 2 s, at most every minute).
  useEffect(() => {
    if (loader === null) return;
    const points = () => bucketsForWidth((container.current?.clientWidth ?? 1000) - margin.l - margin.r);
    loader.rangeLoader.request(rangeOf(window, Date.now() / 1000), points());
    if (window.mode !== "live") return;
    const every_ms = Math.min(60_000, Math.max(2000, (window.span_s * 1000) / points()));
    const timer = setInterval(() => loader.rangeLoader.request(rangeOf(window, Date.now() / 1000), points(), true), every_ms);
    return () => clearInterval(timer);
  }, [loader, window, margin.l, margin.r]);

  // A live plot's "History": its fields over its range in view, as a fixed range.
  useEffect(
    () =>
      historyLink.listen(({ specId: wanted, range }) => {
        if (ALL_PLOTS.some((s) => s.id === wanted)) setSpecId(wanted);
        const next = customWindow(range.from_s, range.to_s);
        if (typeof next !== "string") setWindow(next);
      }),
    [],
  );

  const applyCustom = () => {
    if (custom === null) return;
    const result = customWindow(Date.parse(custom.from) / 1000, Date.parse(custom.to) / 1000);
    if (typeof result === "string") {
      setCustomError(result);
      return;
    }
    setCustomError(null);
    setWindow(result);
  };
  const preset = presetOf(window);
  const shownNow = shown ?? rangeOf(window, Date.now() / 1000);

  return (
    <figure className={`plot plot--${theme} history`} data-testid="history" data-window-mode={window.mode}>
      <figcaption className="plot__header">
        <label>
          <span className="visually-hidden">Plot</span>
          <select aria-label="History plot" data-testid="history-plot-select" value={specId} onChange={(e) => setSpecId(e.target.value)}>
            {ALL_PLOTS.map((s) => (
              <option key={s.id} value={s.id}>
                {s.title}
              </option>
            ))}
          </select>
        </label>
        <span className="plot__controls" role="group" aria-label="Range">
          {RANGE_PRESETS.map((p) => (
            <button
              key={p.id}
              type="button"
              data-testid={`history-range-${p.id}`}
              aria-pressed={preset === p.id}
              onClick={() => {
                setCustom(null);
                setWindow(presetWindow(p.id));
              }}
              title={`The last ${p.label}, following the newest data`}
            >
              {p.label}
            </button>
          ))}
          <button
            type="button"
            data-testid="history-range-custom"
            aria-pressed={custom !== null}
            onClick={() =>
              setCustom(custom === null ? { from: localInput(shownNow.from_s), to: localInput(shownNow.to_s) } : null)
            }
          >
            Custom
          </button>
          {window.mode === "history" && (
            <button
              type="button"
              className="plot__live"
              data-testid="history-live"
              onClick={() => setWindow(backToLive(window))}
              title="Back to the moving window of the newest data"
            >
              Back to live
            </button>
          )}
        </span>
      </figcaption>
      {custom !== null && (
        <form
          className="history__custom"
          onSubmit={(e) => {
            e.preventDefault();
            applyCustom();
          }}
        >
          <label>
            From{" "}
            <input
              type="datetime-local"
              step={1}
              data-testid="history-custom-from"
              value={custom.from}
              onChange={(e) => setCustom({ ...custom, from: e.target.value })}
            />
          </label>{" "}
          <label>
            to{" "}
            <input
              type="datetime-local"
              step={1}
              data-testid="history-custom-to"
              value={custom.to}
              onChange={(e) => setCustom({ ...custom, to: e.target.value })}
            />
          </label>{" "}
          <button type="submit" data-testid="history-custom-apply">
            Show
          </button>
          {customError !== null && (
            <span className="hint" role="alert">
              {customError}
            </span>
          )}
        </form>
      )}
      <div className="plot__frame" style={{ position: "relative" }}>
        <div className="plot__area" ref={container} data-testid="history-plot" style={{ height: `${HEIGHT_PX}px` }} />
        <span className="plot__axis-title plot__axis-title--y" style={{ top: `${HEIGHT_PX / 2}px` }}>
          {titles.y}
        </span>
        {titles.y2 !== null && (
          <span className="plot__axis-title plot__axis-title--y2" style={{ top: `${HEIGHT_PX / 2}px` }}>
            {titles.y2}
          </span>
        )}
      </div>
      <div
        className="history__markers"
        role="group"
        aria-label="Events on the time axis"
        style={{ position: "relative" }}
      >
        {markers.map((m) => (
          <button
            key={m.id}
            type="button"
            className={`history__marker history__marker--${m.kind}`}
            data-testid="history-marker"
            data-kind={m.kind}
            data-kinds={m.events.map((e) => e.kind).join(" ")}
            data-time={m.time_s}
            title={`${m.label} at ${localText(m.time_s)}: show this moment`}
            aria-label={`${m.label} at ${localText(m.time_s)}`}
            onClick={() => setWindow(windowAround(m.time_s))}
            style={{
              position: "absolute",
              // Kept inside the strip at its ends (no overflow of a narrow screen).
              left: `clamp(22px, calc(${margin.l}px + (100% - ${margin.l + margin.r}px) * ${m.at}), calc(100% - 22px))`,
              transform: "translateX(-50%)",
            }}
          >
            {m.kind === "alarm" ? "▲!" : "▲"}
            {m.events.length > 1 ? <small>{m.events.length}</small> : null}
          </button>
        ))}
      </div>
      <p className="history__status">
        <span data-testid="history-range">
          {localText(shownNow.from_s)} – {localText(shownNow.to_s)}
          {window.mode === "live" ? " (live)" : ""}
        </span>{" "}
        {error !== null && (
          <span className="hint" role="alert" data-testid="history-error">
            {error}
          </span>
        )}
        <span className="history__export" role="group" aria-label="Export the range shown">
          Export the range shown:{" "}
          {EXPORT_FORMATS.map((format) => (
            <a
              key={format}
              data-testid={`history-export-${format}`}
              href={exportUrl(robot, shownNow, format, fields)}
              download
              title={`Every frame of the range shown as ${format.toUpperCase()}`}
            >
              {format.toUpperCase()}
            </a>
          )).flatMap((link, i) => (i === 0 ? [link] : [" ", link]))}
        </span>
      </p>
    </figure>
  );
});
