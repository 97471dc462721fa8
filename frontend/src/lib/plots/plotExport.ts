/**
 * Layer: what a plot's "Export the view" covers, and what of it the recording has nothing of
 * (plain TypeScript; no DOM, no Plotly, no React).
 *
 * The export is the service's (`GET …/export`, docs/api.md "History"): every recorded frame of
 * the range. Its range is the one the plot's time axis shows (`LivePlot.visibleRange`): a ring
 * view whose window the recording filled in front of the ring (lib/plots/plotBackfill.ts) shows, and
 * exports, the whole window, not only what reached the page since it opened (issue 38: a 2 min
 * view gave 9 s of CSV). Where the recording has no frame at the start of a range (the recorder
 * was off, the service had just started), the plot says "nothing recorded from … to …", and so
 * does the download (its CSV's last line, docs/api.md "History").
 */
import { formatDateTime_ms } from "../common/dates";
import type { HistoryAnswer, TimeRange } from "./historyView";

/** A leading stretch shorter than this many of the answer's steps (buckets, or 1 s raw) is no gap. */
const GAP_STEPS = 1.5;

/**
 * The start of `range` the recording's `answer` has no frame of (s since the epoch): the whole
 * range when it holds none, from its start to the first frame (or bucket) when that comes later
 * than a step and a half; null when the recording covers the range's start.
 */
export function unrecordedStart(range: TimeRange, answer: Pick<HistoryAnswer, "frames" | "t" | "mode" | "bucket_s">): TimeRange | null {
  const first = answer.t[0];
  if (answer.frames === 0 || first === undefined) return range;
  const step_s = answer.mode === "buckets" ? (answer.bucket_s ?? 1) : 1;
  return first - range.from_s > step_s * GAP_STEPS ? { from_s: range.from_s, to_s: Math.min(first, range.to_s) } : null;
}

/** "nothing recorded from 2026-12-07 04:00:00 to 2026-12-07 04:01:51", in the pages' dates. */
export function nothingRecordedWords(range: TimeRange, format: (epoch_ms: number) => string = (ms) => formatDateTime_ms(ms)): string {
  return `nothing recorded from ${format(range.from_s * 1000)} to ${format(range.to_s * 1000)}`;
}

/**
 * Where a ring view's time axis starts (ms since the epoch) when the recording filled the front
 * of its `window_ms` window ending at `newest_ms`: the window's start, or the recording's first
 * frame when it came later; null when the recording answered nothing (the ring's own start).
 */
export function backfilledFrom_ms(newest_ms: number, window_ms: number, answer: Pick<HistoryAnswer, "frames" | "t">): number | null {
  const first = answer.t[0];
  if (answer.frames === 0 || first === undefined) return null;
  return Math.max(newest_ms - window_ms, first * 1000);
}
