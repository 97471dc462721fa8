/**
 * One live plot: a container Plotly draws into (created once), fed by the coordinator's
 * animation-frame tick. React holds only its configuration (window, pause, picked signals);
 * samples never pass through React state.
 */
import { memo, useEffect, useRef, useState } from "react";
import { historyLink } from "../lib/historyLink";
import { axisTimeToEpochS } from "../lib/historyView";
import { plotlyBackend } from "../lib/plotlyAdapter";
import { DEFAULT_PLOT_HEIGHT_PX, LivePlot, plotMargin, traceColour, type PlotTheme } from "../lib/plotting";
import { ALL_PLOTS, DEFAULT_WINDOW_MS, WINDOWS_MS, axisTitles, tracesOf, type PlotSpec } from "../lib/plots";
import { useRuntime } from "./runtimeContext";

interface Props {
  readonly spec: PlotSpec;
  readonly theme: PlotTheme;
  /** Kiosk: no controls, a static picture. */
  readonly readOnly?: boolean;
  readonly height_px?: number;
}

export const LivePlotView = memo(function LivePlotView({ spec, theme, readOnly = false, height_px }: Props) {
  const { live, coordinator } = useRuntime();
  const container = useRef<HTMLDivElement | null>(null);
  const plotRef = useRef<LivePlot | null>(null);
  const [paused, setPaused] = useState(false);
  const [zoomed, setZoomed] = useState(false);
  const [window_ms, setWindow] = useState(DEFAULT_WINDOW_MS);
  const traces = tracesOf(spec);
  const titles = axisTitles(spec);
  const margin = plotMargin(titles.y2 !== null);
  const height = height_px ?? DEFAULT_PLOT_HEIGHT_PX;
  // The axis titles (with the layout's units) sit in the plot's margins, centred on the plotting
  // area; drawn here rather than by Plotly (see the layout in lib/plotting.ts).
  const titleTop = `${margin.t + (height - margin.t - margin.b) / 2}px`;
  const [visible, setVisible] = useState<boolean[]>(() => traces.map(() => true));

  useEffect(() => {
    const el = container.current;
    if (el === null) return;
    const plot = new LivePlot(spec, live.ring, live.channels, plotlyBackend, {
      window_ms: DEFAULT_WINDOW_MS,
      theme,
      readOnly,
      ...(height_px !== undefined ? { height_px } : {}),
      // The kiosk is read from three metres: no text under 18 px there.
      ...(readOnly ? { fontSize_px: 18 } : {}),
    });
    // Whether it is zoomed away from the moving window is configuration (the button shown).
    plot.onZoomedChange = setZoomed;
    plot.mount(el);
    plotRef.current = plot;
    coordinator.add(plot);
    let observer: IntersectionObserver | null = null;
    if (typeof IntersectionObserver !== "undefined") {
      observer = new IntersectionObserver((entries) => {
        for (const entry of entries) plot.onScreen = entry.isIntersecting;
      });
      observer.observe(el);
    }
    return () => {
      observer?.disconnect();
      plot.onZoomedChange = null;
      coordinator.remove(plot);
      plot.unmount();
      plotRef.current = null;
    };
  }, [spec, live, coordinator, theme, readOnly, height_px]);

  const togglePause = () => {
    const next = !paused;
    setPaused(next);
    plotRef.current?.setPaused(next);
  };
  const backToLive = () => {
    setPaused(false);
    plotRef.current?.backToLive();
  };
  // The panel's history plot shows this plot's fields over the range in view (the zoom, or the
  // window), from the recording: the way from live back into history (components/HistoryView).
  const inHistory = ALL_PLOTS.some((s) => s.id === spec.id);
  const showInHistory = () => {
    const el = container.current;
    const shift_ms = new Date().getTimezoneOffset() * 60_000;
    const x = el !== null ? plotlyBackend.zoomedAxes(el).xaxis : undefined;
    const now_s = Date.now() / 1000;
    const range =
      x !== undefined
        ? { from_s: axisTimeToEpochS(x[0], shift_ms), to_s: axisTimeToEpochS(x[1], shift_ms) }
        : { from_s: now_s - window_ms / 1000, to_s: now_s };
    if (!(range.to_s > range.from_s)) return;
    if (historyLink.show({ specId: spec.id, range })) document.getElementById("history")?.scrollIntoView();
  };
  const exportPng = () => {
    const stamp = new Date().toISOString().replace(/[:.]/g, "-");
    plotRef.current?.exportPng(`${spec.id.replace(/^plot-/, "")}-${stamp}`);
  };
  const chooseWindow = (ms: number) => {
    setWindow(ms);
    plotRef.current?.setWindow(ms);
  };
  const pick = (i: number, on: boolean) => {
    setVisible((v) => v.map((x, k) => (k === i ? on : x)));
    plotRef.current?.setTraceVisible(i, on);
  };

  return (
    <figure
      className={`plot plot--${theme}`}
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
            <button
              type="button"
              className="plot__pause"
              data-testid={`${spec.id}-pause`}
              aria-pressed={paused}
              onClick={togglePause}
              title={paused ? "Resume (data kept buffering while paused)" : "Pause (data keeps buffering)"}
            >
              {paused ? "Resume" : "Pause"}
            </button>
            {(zoomed || paused) && (
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
            {(zoomed || paused) && inHistory && (
              <button
                type="button"
                data-testid={`${spec.id}-history`}
                onClick={showInHistory}
                title="Show the range in view in the history plot, from the recording"
              >
                History
              </button>
            )}
            <button type="button" data-testid={`${spec.id}-png`} onClick={exportPng} title="Save this plot as a PNG image">
              PNG
            </button>
            <select
              aria-label={`${spec.title} window`}
              data-testid={`${spec.id}-window`}
              value={window_ms}
              onChange={(e) => chooseWindow(Number(e.target.value))}
            >
              {WINDOWS_MS.map((w) => (
                <option key={w.ms} value={w.ms}>
                  {w.label}
                </option>
              ))}
            </select>
          </span>
        )}
      </figcaption>
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
          data-testid={spec.id}
          data-points="0"
          data-zoomed="false"
          style={{ height: `${height}px` }}
        />
        <span className="plot__axis-title plot__axis-title--y" data-testid={`${spec.id}-axis-y`} style={{ top: titleTop }}>
          {titles.y}
        </span>
        {titles.y2 !== null && (
          <span className="plot__axis-title plot__axis-title--y2" data-testid={`${spec.id}-axis-y2`} style={{ top: titleTop }}>
            {titles.y2}
          </span>
        )}
      </div>
    </figure>
  );
});
