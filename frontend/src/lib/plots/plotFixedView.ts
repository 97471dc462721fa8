/**
 * Layer: a live plot's fixed view, a range of the past (plain TypeScript; no DOM, no Plotly, no
 * React).
 *
 * A plot of the panel shows a fixed range of the recording after a zoom or pan that reaches
 * before what its ring view holds (or any move in a moving window), a custom range or a
 * marker's jump (docs/architecture.md "Plots: from the ring into the recording"). This module is
 * that view's decisions: whether a new range is a zoom of the ring or a range of the past, what
 * range a Plotly axis shows, whether a range is the one drawn (our own drawing is no move of a
 * person's) or the one a jump showed, and the per-axis revisions that make Plotly take a new
 * range while keeping the person's drag mode. The fetching and the traces are
 * lib/plots/plotRecordingView.ts's. Must not import lib/plots/plotting.ts, Plotly or React.
 */
import { axisTimeToEpochS, type RangeData, type TimeRange } from "./historyView";
import type { PlotView } from "./plotRecordingView";
import type { SpanMs } from "./plotSteps";

/** The range (ms since the epoch) of a Plotly x axis range `x` drawn `shift_ms` off; null if none. */
export function axisSpan_ms(x: readonly unknown[] | undefined, shift_ms: number): SpanMs | null {
  if (x === undefined) return null;
  const from = axisTimeToEpochS(x[0], shift_ms) * 1000;
  const to = axisTimeToEpochS(x[1], shift_ms) * 1000;
  return Number.isFinite(from) && Number.isFinite(to) && to > from ? { from, to } : null;
}

/** Whether two ranges are the same within a thousandth of `a`'s span. */
export function sameSpan(a: SpanMs, b: SpanMs | null): boolean {
  if (b === null) return false;
  const tolerance_ms = (a.to - a.from) / 1000;
  return Math.abs(a.from - b.from) <= tolerance_ms && Math.abs(a.to - b.to) <= tolerance_ms;
}

/**
 * Whether a new range goes into the recording (a fixed view) rather than staying a zoom of the
 * ring view: any move in a view of the recording, or a range reaching before what the ring view
 * holds (`heldFrom_ms`, null: nothing yet) by more than a hundredth of its span.
 */
export function reachesRecording(view: PlotView["kind"], heldFrom_ms: number | null, range: SpanMs): boolean {
  return view !== "ring" || heldFrom_ms === null || range.from < heldFrom_ms - (range.to - range.from) / 100;
}

/** Whether `view` is a fixed view of `range` (to the millisecond). */
export function showsRange(view: PlotView, range: TimeRange): boolean {
  return view.kind === "fixed" && Math.abs(view.from_ms - range.from_s * 1000) < 1 && Math.abs(view.to_ms - range.to_s * 1000) < 1;
}

/**
 * The per-axis `uirevision`s of a plot's drawings of the recording. Plotly keeps a person's axis
 * range within its `uirevision`: where it shows another range than the one drawn now (a jump, a
 * moving window's step), a new x revision makes it take this one. A new range of the past also
 * fits its y axes to its data again (Plotly's zoom-out button widens y as well as x); a moving
 * window's refresh keeps a person's y zoom. Per axis, so the layout's revision keeps the
 * person's drag mode (a pan goes on panning).
 */
export class RecordingRevisions {
  x = 0;
  y = 0;
  /** The answer of the last drawing. */
  private drawnData: RangeData | null = null;

  /** The revisions for drawing `range` of `data` in `view` while Plotly shows `shown` (null: autorange). */
  next(view: PlotView["kind"], range: SpanMs, shown: SpanMs | null, data: RangeData | null): void {
    if (!sameSpan(range, shown)) this.x++;
    if (view === "fixed" && data !== this.drawnData) this.y++;
    this.drawnData = data;
  }

  /** Forget the last answer (the view left the recording). */
  reset(): void {
    this.drawnData = null;
  }
}
