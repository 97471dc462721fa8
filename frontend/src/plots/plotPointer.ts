/**
 * Layer: pure (no DOM, no Plotly, no React). Where the pointer and the keys put a plot's time
 * axis (docs/architecture.md "Plots: one time axis for the panel"): the time under a pixel of
 * the plotting area, the zoom factor of a turn of the mouse wheel, and the cursor's step by key.
 */
import type { PlotMargin } from "../lib/plots/plotAppearance";
import type { SpanMs } from "../lib/plots/plotSteps";

/**
 * The time (ms since the epoch) under `x_px` (from the element's left edge) of a plot
 * `width_px` wide with `margin` showing `range`; null outside the plotting area or without a range.
 */
export function timeAtPixel(x_px: number, width_px: number, margin: PlotMargin, range: SpanMs | null): number | null {
  if (range === null || !(range.to > range.from)) return null;
  const area_px = width_px - margin.l - margin.r;
  const at = (x_px - margin.l) / area_px;
  if (!(area_px > 0) || !(at >= 0) || !(at <= 1)) return null;
  return range.from + at * (range.to - range.from);
}

/** Where `time_ms` is across the plotting area (0 … 1), or null outside `range`. */
export function shareOfRange(time_ms: number, range: SpanMs | null): number | null {
  if (range === null || !(range.to > range.from)) return null;
  const at = (time_ms - range.from) / (range.to - range.from);
  return at >= 0 && at <= 1 ? at : null;
}

/** A notch of a mouse wheel (deltaY 100 px) zooms by this factor: out turning down, in up. */
export const WHEEL_NOTCH_FACTOR = 1.25;

/**
 * The zoom factor of a wheel turn of `deltaY` (WheelEvent's, in `deltaMode` 0 pixels, 1 lines,
 * 2 pages): a notch of 100 px (3 lines) is one WHEEL_NOTCH_FACTOR; a touchpad's small deltas
 * zoom a little each. Over 1 zooms out; 1 for no turn.
 */
export function wheelFactor(deltaY: number, deltaMode = 0): number {
  if (!Number.isFinite(deltaY) || deltaY === 0) return 1;
  const px = deltaMode === 1 ? deltaY * (100 / 3) : deltaMode === 2 ? deltaY * 800 : deltaY;
  // At most four notches at once (a fast flick), so one event never jumps hours.
  const notches = Math.max(-4, Math.min(4, px / 100));
  return WHEEL_NOTCH_FACTOR ** notches;
}

/** The cursor moves by this share of the range in view per key press (Shift + ← / →). */
export const CURSOR_KEY_SHARE = 0.02;

/**
 * The cursor's time after a key press `direction` (−1 earlier, +1 later) from `cursor_ms`, or
 * from the middle of `range` when there is none yet; kept within `range`.
 */
export function cursorAfterKey(cursor_ms: number | null, direction: -1 | 1, range: SpanMs | null): number | null {
  if (range === null || !(range.to > range.from)) return null;
  const span = range.to - range.from;
  const start = cursor_ms !== null && cursor_ms >= range.from && cursor_ms <= range.to ? cursor_ms : null;
  const next = start === null ? range.from + span / 2 : start + direction * span * CURSOR_KEY_SHARE;
  return Math.min(range.to, Math.max(range.from, next));
}
