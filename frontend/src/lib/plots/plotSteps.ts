/**
 * Layer: pure plot-view arithmetic (no DOM, no Plotly).
 *
 * The steps of a plot's time axis that its buttons and keys make (components/LivePlotView.tsx):
 * zoom in and out around the centre of the range in view, pan earlier and later by half of it.
 * `LivePlot.step` (lib/plots/plotting.ts) turns the range a step leads to into a view through the same
 * decision as a person's Plotly zoom or pan (docs/architecture.md "Plots: from the ring into the
 * recording"): a ring zoom inside what the ring holds, the recording otherwise.
 */

export type PlotStep = "zoomIn" | "zoomOut" | "earlier" | "later";

export const PLOT_STEPS: readonly PlotStep[] = ["zoomIn", "zoomOut", "earlier", "later"];

/** A range of the time axis in ms since the epoch. */
export interface SpanMs {
  readonly from: number;
  readonly to: number;
}

/** The narrowest range a zoom in reaches: a few samples at the monitoring values' 100 ms. */
export const MIN_STEP_SPAN_MS = 1000;
/** The widest range a zoom out reaches: the longest window of the picker (7 days). */
export const MAX_STEP_SPAN_MS = 7 * 24 * 3_600_000;

/**
 * The range a step leads to from `range`, or "live" when "Later" reaches now (within a tenth of
 * the span): the moving window again, since the newest data is what live shows and a fixed range
 * ending at now would be out of date at the next frame. A zoom out never reaches past now either: it
 * keeps its span and ends at now (the recording holds nothing newer). Spans stay within
 * [MIN_STEP_SPAN_MS, MAX_STEP_SPAN_MS]; null when the step changes nothing (a zoom at its limit)
 * or `range` is no range.
 */
export function stepRange(range: SpanMs, step: PlotStep, now_ms: number): SpanMs | "live" | null {
  const span = range.to - range.from;
  if (!Number.isFinite(span) || !(span > 0) || !Number.isFinite(now_ms)) return null;
  const centre = range.from + span / 2;
  // Within a tenth of the span of now counts as at now: frames keep coming between the steps, and
  // a range that ends a moment before now shows what live shows.
  const nearNow_ms = now_ms - span / 10;
  const atNow = range.to >= nearNow_ms;
  switch (step) {
    case "zoomIn": {
      const next = Math.max(MIN_STEP_SPAN_MS, span / 2);
      if (next >= span) return null;
      return { from: centre - next / 2, to: centre + next / 2 };
    }
    case "zoomOut": {
      const next = Math.min(MAX_STEP_SPAN_MS, span * 2);
      if (next <= span) return null;
      const to = Math.min(now_ms, centre + next / 2);
      return { from: to - next, to };
    }
    case "earlier":
      return { from: range.from - span / 2, to: range.to - span / 2 };
    case "later": {
      if (atNow) return "live";
      const to = range.to + span / 2;
      return to >= nearNow_ms ? "live" : { from: range.from + span / 2, to };
    }
  }
}

/**
 * The range a zoom by `factor` around `at_ms` leads to (the mouse wheel's: the time under the
 * pointer stays where it is; a factor over 1 zooms out), never past now (a zoom out ending later
 * keeps its span and ends at now), the span within [MIN_STEP_SPAN_MS, MAX_STEP_SPAN_MS]; null
 * when it changes nothing or `range` is no range.
 */
export function zoomAround(range: SpanMs, at_ms: number, factor: number, now_ms: number): SpanMs | null {
  const span = range.to - range.from;
  if (!Number.isFinite(span) || !(span > 0) || !(factor > 0) || !Number.isFinite(at_ms) || !Number.isFinite(now_ms)) return null;
  const next = Math.min(MAX_STEP_SPAN_MS, Math.max(MIN_STEP_SPAN_MS, span * factor));
  if (Math.abs(next - span) < 1e-9 * span) return null;
  const at = Math.min(range.to, Math.max(range.from, at_ms));
  const from = at - ((at - range.from) / span) * next;
  const to = Math.min(now_ms, from + next);
  return { from: to - next, to };
}
