/**
 * Layer: pure plot appearance (no DOM, no Plotly, no React; plain TypeScript).
 *
 * How a live plot (lib/plots/plotting.ts) looks, as Plotly's plain objects: a trace's style, the time
 * axis (our own ticks on a linear axis while the ring view is a static picture, Plotly's date
 * axis while interactive or on the recording), the layout, the config, the margins, the markers
 * of a range of the past. Functions of the plot's definition, its options and the state the
 * caller passes in; nothing here reads the ring, fetches or keeps state.
 * Must not import lib/plots/plotting.ts, lib/plots/plotRecordingView.ts, Plotly or React.
 */
import { axisTimeToEpochS, type Marker } from "./historyView";
import type { PictureDrawing } from "./plotBackend";
import { traceColour, type PlotSpec, type TraceInfo } from "./plots";
import { TICK_SPACING_PX, timeTicks, type TimeTicks } from "./timeTicks";

/**
 * Buckets per window: two points each, so a trace holds at most 400 points in any window, about
 * one per pixel of a plot on a 1920 px panel (three plots abreast). A redraw's time grows with
 * the points (Plotly's path building, the browser's path parsing and rasterising): 600 points
 * cost about a third more for nothing the eye sees.
 */
export const BUCKETS_PER_WINDOW = 200;

export const DEFAULT_PLOT_HEIGHT_PX = 240;

/** Tick labels' size (px) unless the options say otherwise. */
const DEFAULT_FONT_SIZE_PX = 11;

/** Plot margins (px) around the plotting area; the view places the axis titles in them. */
export interface PlotMargin {
  readonly l: number;
  readonly r: number;
  readonly t: number;
  readonly b: number;
}

export function plotMargin(twoAxes: boolean): PlotMargin {
  return { l: 64, r: twoAxes ? 64 : 16, t: 8, b: 36 };
}

export type PlotTheme = "light" | "dark";

/** The options of a plot that decide how it looks (a part of `LivePlotOptions`). */
export interface PlotLook {
  readonly theme: PlotTheme;
  /** Kiosk: a static picture, no zoom, no mode bar, no hover. */
  readonly readOnly: boolean;
  readonly height_px?: number;
  /** Tick labels' size (px); the kiosk's are large (no text under 18 px there). */
  readonly fontSize_px?: number;
}

/** Axis ranges by Plotly axis name ("xaxis", "yaxis", "yaxis2"), as Plotly reports a zoom. */
export type AxisRanges = Readonly<Record<string, readonly unknown[]>>;

/** Whether the plot has a second y axis (on the right). */
export function hasSecondAxis(spec: PlotSpec): boolean {
  return spec.series.some((s) => s.axis === "y2");
}

/** The plotting area's width (px) in an element `width_px` wide (NaN for NaN). */
export function plotAreaWidth_px(spec: PlotSpec, width_px: number): number {
  const margin = plotMargin(hasSecondAxis(spec));
  return width_px - margin.l - margin.r;
}

/** A line trace's style (no data): `i` is the trace's index in `tracesOf(spec)`. */
export function traceStyle(trace: TraceInfo, i: number, visible: boolean, readOnly: boolean): object {
  return {
    type: "scatter",
    mode: "lines",
    name: trace.name,
    yaxis: trace.axis,
    visible,
    // 1 px on the panel: the browser strokes a line of at most 1 px as a hairline, which it
    // rasterises at about a quarter of the cost of a 1.5 px stroke (bench/ui: raster CPU per
    // redraw). The kiosk, read from three metres, keeps the heavier line.
    line: { width: readOnly ? 1.5 : 1, color: traceColour(i), dash: trace.axis === "y2" ? "dot" : "solid" },
    connectgaps: false,
    // The value with the layout's unit ("J 1: 12.35 degree"), the time in the hover's header.
    ...(readOnly ? { hoverinfo: "skip" } : { hovertemplate: `${trace.name}: %{y:.4~r} ${trace.field.unit}<extra></extra>` }),
    hoverlabel: { namelength: -1 },
  };
}

/** The traces of a plot with no data yet (`visible[i]`: the signal picker's choice). */
export function emptyTraces(traces: readonly TraceInfo[], visible: readonly boolean[], readOnly: boolean): object[] {
  return traces.map((trace, i) => ({ ...traceStyle(trace, i, visible[i] ?? true, readOnly), x: [], y: [] }));
}

/** Time ticks over [from, to] (numeric dates) in a plotting area `areaWidth_px` wide. */
export function ticksOver(from: number, to: number, areaWidth_px: number, fontSize_px: number | undefined): TimeTicks {
  // Labels of larger text (the kiosk's) need more room each.
  const spacing_px = Math.max(TICK_SPACING_PX, 9 * (fontSize_px ?? DEFAULT_FONT_SIZE_PX));
  return timeTicks(from, to, areaWidth_px, spacing_px);
}

/** Time ticks for the moving window of `window_ms` ending at `newestX` (a numeric date, shifted). */
export function ticksBefore(newestX: number, window_ms: number, areaWidth_px: number, fontSize_px: number | undefined): TimeTicks {
  // A little over the window: the oldest points kept may reach a bucket further back.
  return ticksOver(newestX - window_ms * 1.05, newestX, areaWidth_px, fontSize_px);
}

/** The time axis of a drawing. */
export interface TimeAxis {
  /** Plotly's `xaxis` (without a zoom's range). */
  readonly axis: object;
  /** A zoom's x range as numbers, which the layout sets on the axis; null: none. */
  readonly range: number[] | null;
  /** Drawn with our own ticks that each live update moves (`ticksBefore`). */
  readonly ownTicks: boolean;
}

/** The colours of a plot in `theme`: paper (and plotting area), text, grid lines. */
export function plotColours(theme: PlotTheme): { readonly paper: string; readonly text: string; readonly grid: string } {
  const dark = theme === "dark";
  return { paper: dark ? "#12161b" : "#ffffff", text: dark ? "#d8dde3" : "#222", grid: gridColour(theme) };
}

/** The tick labels' size (px) of a plot with `look`. */
export function fontSize_px(look: PlotLook): number {
  return look.fontSize_px ?? DEFAULT_FONT_SIZE_PX;
}

/** Plotly's default font, the tick labels'. */
export const PLOT_FONT_FAMILY = '"Open Sans", verdana, arial, sans-serif';

function gridColour(theme: PlotTheme): string {
  return theme === "dark" ? "#2f3740" : "#e3e3e3";
}

/**
 * The time axis. A live plot nobody points at (`ringStatic`: the ring view, drawn as a static
 * picture) draws it as a linear axis with our own ticks: a date axis reads each sample's time
 * through Plotly's date parser and works out date ticks on every redraw (lib/plots/timeTicks.ts). An
 * interactive plot or a view of the recording keeps the date axis, for its hover and for zooming
 * into dates. `newestX`: the ring's newest frame as a numeric date (shifted; NaN: none).
 */
export function timeAxis(
  look: PlotLook,
  ringStatic: boolean,
  zoom: AxisRanges,
  newestX: number,
  window_ms: number,
  areaWidth_px: number,
): TimeAxis {
  // "allow": Plotly otherwise measures every tick label on every redraw (a quarter of its time).
  const common = { autorange: true, gridcolor: gridColour(look.theme), ticklabeloverflow: "allow" };
  if (!ringStatic) return { axis: { ...common, type: "date" }, range: null, ownTicks: false };
  // A zoom carried over from the date axis: its range may be Plotly's date text.
  const zoomed = zoom.xaxis?.map((v) => (typeof v === "number" ? v : axisTimeToEpochS(v, 0) * 1000)) ?? null;
  const ticks =
    zoomed !== null
      ? ticksOver(zoomed[0] ?? Number.NaN, zoomed[1] ?? Number.NaN, areaWidth_px, look.fontSize_px)
      : ticksBefore(newestX, window_ms, areaWidth_px, look.fontSize_px);
  return { axis: { ...common, type: "linear", tickmode: "array", ...ticks }, range: zoomed, ownTicks: zoomed === null };
}

/** A zoom's axis range as numbers (numeric dates for x; Plotly's date text read as UTC), or null. */
function numericRange(range: readonly unknown[] | undefined): [number, number] | null {
  if (range === undefined) return null;
  const [a, b] = range.map((v) => (typeof v === "number" ? v : axisTimeToEpochS(v, 0) * 1000));
  return a !== undefined && b !== undefined && Number.isFinite(a) && Number.isFinite(b) ? [a, b] : null;
}

/** What a static picture (lib/plots/plotBackend.ts `StaticPicture`) draws with `zoom` in force. */
export function pictureDrawing(zoom: AxisRanges, visible: readonly boolean[]): PictureDrawing {
  const y = numericRange(zoom.yaxis);
  const y2 = numericRange(zoom.yaxis2);
  return { visible, x: numericRange(zoom.xaxis), y: { ...(y !== null ? { yaxis: y } : {}), ...(y2 !== null ? { yaxis2: y2 } : {}) } };
}

/**
 * Plotly's layout: `revision` names the layout's `uirevision` (a new one drops a person's zoom
 * and drag mode); `interactive` hovers; `zoom` sets those axes' ranges (autorange off).
 */
export function plotLayout(
  spec: PlotSpec,
  look: PlotLook,
  revision: number,
  interactive: boolean,
  time: TimeAxis,
  zoom: AxisRanges,
): Record<string, unknown> {
  const dark = look.theme === "dark";
  const fg = dark ? "#d8dde3" : "#222";
  const twoAxes = hasSecondAxis(spec);
  if (time.range !== null) zoom = { ...zoom, xaxis: time.range };
  const layout: Record<string, unknown> = {
    uirevision: `${spec.id}:${revision}`,
    autosize: true,
    height: look.height_px ?? DEFAULT_PLOT_HEIGHT_PX,
    margin: plotMargin(twoAxes),
    showlegend: false,
    paper_bgcolor: dark ? "#12161b" : "#ffffff",
    plot_bgcolor: dark ? "#12161b" : "#ffffff",
    font: { color: fg, size: look.fontSize_px ?? DEFAULT_FONT_SIZE_PX },
    // Hover whenever the plot is interactive (the pointer on it, or paused): live too.
    hovermode: interactive ? "x" : false,
    // No Plotly axis titles: the view draws them (axisTitles in plots.ts) beside the plot. With a
    // title, Plotly measures every tick label against it on every redraw and caches each
    // measurement under the label's pixel position: with autoranged axes the labels keep
    // moving, and its text-measurement cache grew by hundreds of entries a minute.
    // "allow": Plotly otherwise measures every tick label on every redraw (a quarter of its time).
    xaxis: time.axis,
    yaxis: {
      autorange: true,
      gridcolor: gridColour(look.theme),
      zeroline: false,
      ticklabeloverflow: "allow",
    },
  };
  if (twoAxes) {
    layout.yaxis2 = {
      autorange: true,
      overlaying: "y",
      side: "right",
      zeroline: false,
      showgrid: false,
      ticklabeloverflow: "allow",
    };
  }
  for (const [axis, range] of Object.entries(zoom)) {
    const current = layout[axis];
    if (typeof current === "object" && current !== null) {
      layout[axis] = { ...current, autorange: false, range: [...range] };
    }
  }
  return layout;
}

/** Plotly's config: a static picture (no zoom layer, no mode bar), or interactive. */
export function plotConfig(interactive: boolean): object {
  if (!interactive) {
    return { staticPlot: true, displayModeBar: false, responsive: true };
  }
  return {
    responsive: true,
    displaylogo: false,
    // Plotly's "Double-click to zoom back out" notice would sit over the plot's header (its
    // buttons): "Back to live" and the mode bar's autoscale say the same.
    showTips: false,
    // Not "Share chart…" (it uploads the plot to Plotly's cloud: nothing of a cell leaves it so).
    modeBarButtonsToRemove: ["select2d", "lasso2d", "toImage", "sendChartToCloud"],
  };
}

/** Markers of a range as dotted lines across the plot on the time axis (`shift_ms` as the data's). */
export function markerShapes(markers: readonly Marker[], shift_ms: number): object[] {
  return markers.map((m) => ({
    type: "line",
    xref: "x",
    yref: "paper",
    x0: m.time_s * 1000 - shift_ms,
    x1: m.time_s * 1000 - shift_ms,
    y0: 0,
    y1: 1,
    line: { color: m.kind === "alarm" ? "#D55E00" : "#888", width: 1, dash: "dot" },
  }));
}

function withRevision(layout: Record<string, unknown>, axis: string, revision: string): void {
  const a = layout[axis];
  if (typeof a === "object" && a !== null) layout[axis] = { ...a, uirevision: revision };
}

/**
 * A drawing of the recording's layout: `layout` with the markers' `shapes` and a `uirevision`
 * per axis (`xRevision` for x, `yRevision` for both y axes), so a new revision of one axis makes
 * Plotly take its range while the layout's own revision keeps the person's drag mode.
 */
export function historyLayout(
  layout: Record<string, unknown>,
  shapes: object[],
  xRevision: number,
  yRevision: number,
): Record<string, unknown> {
  const drawn: Record<string, unknown> = { ...layout, shapes };
  withRevision(drawn, "xaxis", `x${xRevision}`);
  withRevision(drawn, "yaxis", `y${yRevision}`);
  withRevision(drawn, "yaxis2", `y${yRevision}`);
  return drawn;
}
