/**
 * One live plot: a container Plotly draws into (created once), fed by the coordinator's
 * animation-frame tick. React holds only its configuration (window, pause, picked signals) and,
 * when it shows the recording, the range shown, its event markers and the export links;
 * samples never pass through React state.
 *
 * In the panel (a PlotHistoryContext provider) the plot reaches the recording: long windows
 * (15 min … 7 days) and a custom range in its window picker, a zoom or pan past the ring
 * fetched from the history API, markers whose click moves every plot of the panel, and the
 * export of the range in view (docs/architecture.md "Plots: from the ring into the recording").
 * There it is linked to the panel's one time axis and cursor (plots/plotWiring.ts; a "Linked"
 * box unlinks it), and while nobody points at it a canvas picture draws it rather than Plotly
 * (plots/canvasPlot.ts; `?plotPicture=off` keeps Plotly, bench/ui's baseline). The kiosk's plots,
 * never pointed at, are always the picture: Plotly's redraws of its two plots ten times a second
 * kept three quarters of the kiosk's main thread busy (a fifth with the picture).
 */
import { memo, useEffect, useRef, useState, type KeyboardEvent, type MouseEvent } from "react";
import {
  EXPORT_FORMATS,
  customRange,
  exportUrl,
  fieldsOf,
  MARKER_WIDTH_PX,
  MARKER_WIDTH_TOUCH_PX,
  markerSpacing,
  markersOf,
  rangeOfMarker,
  type ExportFormat,
  type TimeRange,
} from "../lib/plots/historyView";
import { formatDateTime_ms, formatInputDateTime, parseInputDateTime } from "../lib/common/dates";
import { nothingRecordedWords } from "../lib/plots/plotExport";
import { plotlyBackend } from "../lib/plots/plotlyAdapter";
import { DEFAULT_PLOT_HEIGHT_PX, plotMargin, type PlotTheme } from "../lib/plots/plotAppearance";
import type { HistoryShown } from "../lib/plots/plotRecordingView";
import { LivePlot } from "../lib/plots/plotting";
import { DEFAULT_WINDOW_MS, HISTORY_WINDOWS_MS, WINDOWS_MS, axisTitles, traceColour, tracesOf, type PlotSpec } from "../lib/plots/plots";
import type { PlotStep } from "../lib/plots/plotSteps";
import { CanvasPlot, followAreaSize } from "../plots/canvasPlot";
import { STEP_BUTTONS, plotKeyAction } from "../plots/plotKeys";
import { PlotWiring } from "../plots/plotWiring";
import { usePlotHistory } from "./plotHistory";
import { useRuntime } from "./runtimeContext";
import "../styles/history.css";
import "../styles/plotSteps.css";

interface Props {
  readonly spec: PlotSpec;
  readonly theme: PlotTheme;
  /** Kiosk: no controls, a static picture. */
  readonly readOnly?: boolean;
  readonly height_px?: number;
  /** The window it opens with (ms; the kiosk's setting), else DEFAULT_WINDOW_MS. */
  readonly initialWindow_ms?: number;
}

/** A `datetime-local` input's value (the plant's time, seconds) for epoch seconds. */
function localInput(time_s: number): string {
  return formatInputDateTime(time_s * 1000);
}

/** The pages' one date format, in the plant's zone (lib/common/dates.ts). */
function localText(time_s: number): string {
  return formatDateTime_ms(time_s * 1000);
}

/** What the markers' badges mean, shown under them (issue 38: "▲!22" read as a code). */
const MARKER_KEY = "Events on the time axis: ▲ an event, ▲! an alarm or an emergency stop, a number beside it: that many events together (zoom in to tell them apart). A click shows that moment in every plot.";

/**
 * A marker's accessible name: its visible count first (WCAG 2.5.3, the name holds the text the
 * button shows), then its events in words and the time.
 */
function markerName(m: { readonly events: readonly unknown[]; readonly label: string }, at: string): string {
  const count = m.events.length;
  return `${count > 1 ? `${count} events: ` : ""}${m.label} at ${at}`;
}

const CUSTOM = "custom";
const RANGE = "range";

/**
 * How far off the screen a plot's picture canvas is still shown (an IntersectionObserver's
 * margin): a scroll's step or two, not the next row of plots (each shown canvas costs every commit).
 */
const PICTURE_MARGIN = "40px 0px";

/** The kiosk is read from three metres: no text under this size on its plots (CSS px). */
const KIOSK_FONT_SIZE_PX = 18;

/** Plots draw a canvas picture while nobody points at them, unless the page says not. */
function pictureWanted(): boolean {
  return typeof window === "undefined" || new URLSearchParams(window.location.search).get("plotPicture") !== "off";
}

export const LivePlotView = memo(function LivePlotView({ spec, theme, readOnly = false, height_px, initialWindow_ms }: Props) {
  const runtime = useRuntime();
  const { live, coordinator } = runtime;
  const access = usePlotHistory();
  const robot = runtime.robot;
  // The recording is reached from the panel's plots (not the kiosk's) of a named robot.
  const history = !readOnly && access !== null && robot !== null ? { access, robot } : null;
  const fields = fieldsOf(spec);
  const container = useRef<HTMLDivElement | null>(null);
  const canvasRef = useRef<HTMLCanvasElement | null>(null);
  const cursorRef = useRef<HTMLParagraphElement | null>(null);
  const cursorLineRef = useRef<HTMLDivElement | null>(null);
  const plotRef = useRef<LivePlot | null>(null);
  const wiringRef = useRef<PlotWiring | null>(null);
  // Linked to the panel's time axis (configuration: kept across a rebuild of the plot).
  const [linked, setLinked] = useState(true);
  const linkedRef = useRef(linked);
  const [paused, setPaused] = useState(false);
  const [zoomed, setZoomed] = useState(false);
  const [window_ms, setWindow] = useState(initialWindow_ms ?? DEFAULT_WINDOW_MS);
  // The plot is rebuilt with the window picked so far (a theme change recreates it).
  const windowRef = useRef(window_ms);
  const [shown, setShown] = useState<HistoryShown | null>(null);
  // The start of the view the recording has nothing of: said beside the export links.
  const [unrecorded, setUnrecorded] = useState<TimeRange | null>(null);
  // The plot's width when it last drew the recording: how close markers may be on screen.
  const [width_px, setWidth] = useState(0);
  const [custom, setCustom] = useState<{ from: string; to: string } | null>(null);
  const [customError, setCustomError] = useState<string | null>(null);
  const traces = tracesOf(spec);
  const titles = axisTitles(spec);
  const margin = plotMargin(titles.y2 !== null);
  const height = height_px ?? DEFAULT_PLOT_HEIGHT_PX;
  // The axis titles (with the layout's units) sit in the plot's margins, centred on the plotting
  // area; drawn here rather than by Plotly (see the layout in lib/plots/plotting.ts).
  const titleTop = `${margin.t + (height - margin.t - margin.b) / 2}px`;
  const [visible, setVisible] = useState<boolean[]>(() => traces.map(() => true));
  const historyAccess = history?.access ?? null;
  const pauseButton = useRef<HTMLButtonElement | null>(null);
  const refocusPause = useRef(false);
  useEffect(() => {
    if (!refocusPause.current) return;
    refocusPause.current = false;
    pauseButton.current?.focus();
  });
  const historyRobot = history?.robot ?? null;

  useEffect(() => {
    const el = container.current;
    if (el === null) return;
    const canvas = canvasRef.current;
    const look = { theme, readOnly, ...(height_px !== undefined ? { height_px } : {}), ...(readOnly ? { fontSize_px: KIOSK_FONT_SIZE_PX } : {}) };
    const picture = canvas !== null && pictureWanted() ? new CanvasPlot(canvas, spec, tracesOf(spec), look) : null;
    const plot = new LivePlot(spec, live.ring, live.channels, plotlyBackend, {
      ...look,
      window_ms: windowRef.current,
      ...(historyAccess !== null && historyRobot !== null
        ? { history: { fetchRange: historyAccess.fetcher(historyRobot, fields) } }
        : {}),
      ...(picture !== null ? { staticPicture: picture } : {}),
    });
    // Whether it is zoomed away from the moving window is configuration (the button shown).
    plot.onZoomedChange = setZoomed;
    // A window picked here or on a linked plot (lib/plots/timeRange.ts): the picker shows it.
    plot.onWindowChange = (ms) => {
      windowRef.current = ms;
      setWindow(ms);
      setCustom(null);
    };
    // Each drawing of the recording (not each frame): the range, its markers, an error.
    plot.onHistory = (next) => {
      setShown(next.view === "ring" ? null : next);
      setUnrecorded(plot.unrecorded());
      setWidth(el.clientWidth);
      setPaused(plot.isPaused);
    };
    plot.mount(el);
    plotRef.current = plot;
    coordinator.add(plot);
    const cursorOut = cursorRef.current;
    const cursorLine = cursorLineRef.current;
    // The panel's one time axis and cursor, the wheel's zoom, the picture's size.
    const wiring =
      readOnly || cursorOut === null || cursorLine === null
        ? null
        : new PlotWiring(plot, { area: el, cursorOut, cursorLine }, historyAccess?.timeRange ?? null, linkedRef.current);
    wiringRef.current = wiring;
    const stopSizing = picture !== null ? followAreaSize(picture, el, () => plot.redraw()) : null;
    let observer: IntersectionObserver | null = null;
    let nearObserver: IntersectionObserver | null = null;
    if (typeof IntersectionObserver !== "undefined") {
      observer = new IntersectionObserver((entries) => {
        for (const entry of entries) plot.onScreen = entry.isIntersecting;
      });
      observer.observe(el);
      // The picture's canvas is hidden off the screen (plots/canvasPlot.ts `setInView`), and
      // shown a little before it scrolls in, so that it is there when it comes.
      if (picture !== null) {
        nearObserver = new IntersectionObserver(
          (entries) => {
            for (const entry of entries) picture.setInView(entry.isIntersecting);
          },
          { rootMargin: PICTURE_MARGIN },
        );
        nearObserver.observe(el);
      }
    }
    return () => {
      observer?.disconnect();
      nearObserver?.disconnect();
      wiring?.dispose();
      wiringRef.current = null;
      stopSizing?.();
      plot.onZoomedChange = null;
      plot.onWindowChange = null;
      plot.onHistory = null;
      coordinator.remove(plot);
      plot.unmount();
      plotRef.current = null;
      setShown(null);
      setUnrecorded(null);
    };
  }, [spec, live, coordinator, theme, readOnly, height_px, historyAccess, historyRobot, fields]);

  const togglePause = () => {
    const next = !paused;
    setPaused(next);
    plotRef.current?.setPaused(next);
  };
  const backToLive = (e?: MouseEvent<HTMLButtonElement>) => {
    // The button goes once live: its focus moves on to Pause (drawn again), not to the page.
    refocusPause.current = e !== undefined && document.activeElement === e.currentTarget;
    setPaused(false);
    setCustom(null);
    // Every linked plot of the panel follows (lib/plots/timeRange.ts).
    plotRef.current?.backToLive();
  };
  const link = (on: boolean) => {
    setLinked(on);
    linkedRef.current = on;
    wiringRef.current?.setLinked(on);
  };
  const step = (s: PlotStep) => plotRef.current?.step(s);
  const onAreaKey = (e: KeyboardEvent<HTMLDivElement>) => {
    if (e.altKey || e.ctrlKey || e.metaKey) return;
    const action = plotKeyAction(e.key, e.shiftKey);
    if (action === null) return;
    e.preventDefault();
    if ("step" in action) step(action.step);
    else wiringRef.current?.cursorKey(action.cursor);
  };
  const exportPng = () => {
    const stamp = formatInputDateTime(Date.now()).replace(/:/g, "-");
    plotRef.current?.exportPng(`${spec.id.replace(/^plot-/, "")}-${stamp}`);
  };
  const chooseWindow = (value: string) => {
    if (value === RANGE) return;
    if (value === CUSTOM) {
      const r = plotRef.current?.visibleRange() ?? null;
      const now_s = Date.now() / 1000;
      setCustom({ from: localInput(r?.from_s ?? now_s - 600), to: localInput(r?.to_s ?? now_s) });
      setCustomError(null);
      return;
    }
    const ms = Number(value);
    setCustom(null);
    setWindow(ms);
    windowRef.current = ms;
    plotRef.current?.setWindow(ms);
  };
  const applyCustom = () => {
    if (custom === null) return;
    const result = customRange(parseInputDateTime(custom.from) / 1000, parseInputDateTime(custom.to) / 1000);
    if (typeof result === "string") {
      setCustomError(result);
      return;
    }
    setCustomError(null);
    setCustom(null);
    plotRef.current?.showRange(result);
  };
  const pick = (i: number, on: boolean) => {
    setVisible((v) => v.map((x, k) => (k === i ? on : x)));
    plotRef.current?.setTraceVisible(i, on);
  };

  const fixed = shown?.view === "fixed";
  const range: TimeRange | null = shown?.range ?? null;
  // Touch screens make every button a 44 px target: markers further apart there.
  const touch = typeof window.matchMedia === "function" && window.matchMedia("(pointer: coarse)").matches;
  const spacing = markerSpacing(width_px - margin.l - margin.r, touch ? MARKER_WIDTH_TOUCH_PX : MARKER_WIDTH_PX);
  const markers = shown !== null && range !== null ? markersOf(shown.events, range, spacing) : [];
  const windowValue = fixed ? RANGE : custom !== null ? CUSTOM : String(window_ms);
  // On the ring the range in view moves: the link's range is renewed at the click (below).
  const now_s = Date.now() / 1000;
  const linkRange = range ?? { from_s: now_s - window_ms / 1000, to_s: now_s };
  const exportHref = (format: ExportFormat) => (historyRobot === null ? undefined : exportUrl(historyRobot, linkRange, format, fields));
  const exportNow = (format: ExportFormat) => (e: MouseEvent<HTMLAnchorElement>) => {
    const r = plotRef.current?.visibleRange() ?? null;
    if (historyRobot !== null && r !== null) e.currentTarget.href = exportUrl(historyRobot, r, format, fields);
  };

  return (
    <figure
      className={`plot plot--${theme}`}
      data-testid={`${spec.id}-figure`}
      data-view={shown?.view ?? "ring"}
      data-window-ms={window_ms}
      data-linked={readOnly ? undefined : String(linked)}
      onPointerEnter={readOnly ? undefined : () => plotRef.current?.setPointerInside(true)}
      onPointerLeave={
        readOnly
          ? undefined
          : (e) => {
              // A zoom drag covers the page with Plotly's drag layer: that is no leaving.
              if (e.buttons === 0) plotRef.current?.setPointerInside(false);
            }
      }
    >
      <figcaption className="plot__header">
        <span className="plot__title">{spec.title}</span>
        {!readOnly && (
          <span className="plot__controls">
            <span className="plot__steps" role="group" aria-label={`${spec.title}: time axis`}>
              {STEP_BUTTONS.map((b) => (
                <button
                  key={b.step}
                  type="button"
                  className="plot__step"
                  data-testid={`${spec.id}-${b.step}`}
                  aria-label={b.label}
                  title={b.title}
                  onClick={() => step(b.step)}
                >
                  {b.text}
                </button>
              ))}
            </span>
            {!fixed && (
              <button
                ref={pauseButton}
                type="button"
                className="plot__pause"
                data-testid={`${spec.id}-pause`}
                aria-pressed={paused}
                onClick={togglePause}
                title={paused ? "Resume (data kept buffering while paused)" : "Pause (data keeps buffering)"}
              >
                {paused ? "Resume" : "Pause"}
              </button>
            )}
            {(zoomed || paused || fixed) && (
              <button
                type="button"
                className="plot__live"
                data-testid={`${spec.id}-live`}
                onClick={backToLive}
                title="Back to the moving window of the newest data"
              >
                Back to live
              </button>
            )}
            <button type="button" data-testid={`${spec.id}-png`} onClick={exportPng} title="Save this plot as a PNG image">
              PNG
            </button>
            {history !== null && (
              <label
                className="plot__linked"
                title="Linked: zoom, pan, window, back to live and the cursor act on every linked plot of the panel together"
              >
                <input type="checkbox" data-testid={`${spec.id}-linked`} checked={linked} onChange={(e) => link(e.target.checked)} />
                Linked
              </label>
            )}
            <select
              aria-label={`${spec.title} window`}
              data-testid={`${spec.id}-window`}
              value={windowValue}
              onChange={(e) => chooseWindow(e.target.value)}
            >
              {WINDOWS_MS.map((w) => (
                <option key={w.ms} value={String(w.ms)}>
                  {w.label}
                </option>
              ))}
              {history !== null &&
                HISTORY_WINDOWS_MS.map((w) => (
                  <option key={w.ms} value={String(w.ms)}>
                    {w.label}
                  </option>
                ))}
              {fixed && <option value={RANGE}>Range of the past</option>}
              {history !== null && <option value={CUSTOM}>Custom…</option>}
            </select>
          </span>
        )}
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
              data-testid={`${spec.id}-custom-from`}
              value={custom.from}
              onChange={(e) => setCustom({ ...custom, from: e.target.value })}
            />
          </label>{" "}
          <label>
            to{" "}
            <input
              type="datetime-local"
              step={1}
              data-testid={`${spec.id}-custom-to`}
              value={custom.to}
              onChange={(e) => setCustom({ ...custom, to: e.target.value })}
            />
          </label>{" "}
          <button type="submit" data-testid={`${spec.id}-custom-apply`}>
            Show
          </button>
          <button type="button" onClick={() => setCustom(null)}>
            Cancel
          </button>
          {customError !== null && (
            <span className="hint" role="alert">
              {customError}
            </span>
          )}
        </form>
      )}
      {!readOnly && (
        <div className="plot__signals" role="group" aria-label={`${spec.title} signals`}>
          {traces.map((trace, i) => (
            <label key={trace.name} className="plot__signal" title={`${trace.field.description} [${trace.field.unit}]`}>
              <input
                type="checkbox"
                data-testid={`${spec.id}-signal-${i}`}
                checked={visible[i] ?? true}
                onChange={(e) => pick(i, e.target.checked)}
              />
              <span className="plot__swatch" style={{ background: traceColour(i) }} aria-hidden="true" />
              {trace.name}
            </label>
          ))}
        </div>
      )}
      {readOnly && (
        <div className="plot__legend" aria-hidden="true">
          {traces.map((trace, i) => (
            <span key={trace.name} className="plot__signal">
              <span className="plot__swatch" style={{ background: traceColour(i) }} />
              {trace.name}
            </span>
          ))}
        </div>
      )}
      <div className="plot__frame">
        <div
          className="plot__area"
          ref={container}
          // Focusable (not on the kiosk): arrow keys pan, + and − zoom; focus makes the plot
          // interactive as the pointer does.
          {...(readOnly
            ? {}
            : {
                tabIndex: 0,
                role: "group",
                "aria-label": `${spec.title} plot: ← and → earlier and later, + and − zoom (or Ctrl + wheel), Shift + ← and → move the cursor`,
                onKeyDown: onAreaKey,
                onFocus: () => plotRef.current?.setFocusInside(true),
                onBlur: () => plotRef.current?.setFocusInside(false),
              })}
          data-testid={spec.id}
          data-points="0"
          data-zoomed="false"
          data-view="ring"
          style={{ height: `${height}px` }}
        />
        {/* The static picture over Plotly's plot while nobody points at it (plots/canvasPlot.ts). */}
        <canvas className="plot__picture" ref={canvasRef} aria-hidden="true" style={{ height: `${height}px`, visibility: "hidden" }} />
        {!readOnly && <div className="plot__cursor-line" ref={cursorLineRef} aria-hidden="true" hidden />}
        <span className="plot__axis-title plot__axis-title--y" data-testid={`${spec.id}-axis-y`} style={{ top: titleTop }}>
          {titles.y}
        </span>
        {titles.y2 !== null && (
          <span className="plot__axis-title plot__axis-title--y2" data-testid={`${spec.id}-axis-y2`} style={{ top: titleTop }}>
            {titles.y2}
          </span>
        )}
      </div>
      {!readOnly && <p className="plot__cursor" ref={cursorRef} data-testid={`${spec.id}-cursor`} hidden />}
      {shown !== null && (
        <div className="history__markers" role="group" aria-label={`${spec.title}: events on the time axis`}>
          {markers.map((m) => (
            <button
              key={m.id}
              type="button"
              className={`history__marker history__marker--${m.kind}`}
              data-testid={`${spec.id}-marker`}
              data-kind={m.kind}
              data-kinds={m.events.map((e) => e.kind).join(" ")}
              data-time={m.time_s}
              data-last={m.last_s}
              title={`${markerName(m, localText(m.time_s))}: show this moment in every plot`}
              aria-label={markerName(m, localText(m.time_s))}
              onClick={() => plotRef.current?.showRange(rangeOfMarker(m))}
              style={{
                // Kept inside the strip at its ends (no overflow of a narrow screen).
                left: `clamp(22px, calc(${margin.l}px + (100% - ${margin.l + margin.r}px) * ${m.at}), calc(100% - 22px))`,
              }}
            >
              <span aria-hidden="true">{m.kind === "alarm" ? "▲!" : "▲"}</span>
              {m.events.length > 1 ? <small>{m.events.length}</small> : null}
            </button>
          ))}
        </div>
      )}
      {shown !== null && markers.length > 0 && (
        <p className="history__key" data-testid={`${spec.id}-marker-key`}>
          {MARKER_KEY}
        </p>
      )}
      {history !== null && (
        <p className="history__status">
          {shown !== null && range !== null && (
            <span data-testid={`${spec.id}-range`}>
              {localText(range.from_s)} – {localText(range.to_s)}
              {shown.view === "moving" ? " (live)" : ""}
            </span>
          )}
          {shown?.error != null && (
            <span className="hint" role="alert" data-testid={`${spec.id}-history-error`}>
              {shown.error}
            </span>
          )}
          {unrecorded !== null && (
            <span className="hint" data-testid={`${spec.id}-unrecorded`}>
              {nothingRecordedWords(unrecorded)}
            </span>
          )}
          <span className="history__export" role="group" aria-label={`${spec.title}: export the range in view`}>
            Export the view:{" "}
            {EXPORT_FORMATS.map((format) => (
              <a
                key={format}
                data-testid={`${spec.id}-export-${format}`}
                href={exportHref(format)}
                onClick={exportNow(format)}
                download
                title={`Every frame of ${spec.title} in the range in view, as ${format.toUpperCase()}`}
              >
                {format.toUpperCase()}
              </a>
            )).flatMap((link, i) => (i === 0 ? [link] : [" ", link]))}
          </span>
        </p>
      )}
    </figure>
  );
});
