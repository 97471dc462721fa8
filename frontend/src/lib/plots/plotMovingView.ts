/**
 * Layer: a live plot's moving window from the recording (plain TypeScript; no DOM, no Plotly,
 * no React).
 *
 * A window picked longer than the ring holds (15 min … 7 days) is a moving view: the history
 * API's decimated range ending at the newest frame, asked again as about one bucket fills, with
 * the ring's newest seconds drawn on top (docs/architecture.md "Plots: from the ring into the
 * recording"). This module is its policy: which view a picked window is, and what a due refresh
 * does (ask now, or only schedule the next turn while the plot is out of view). The refresh's
 * timer and the fetching are lib/plots/plotRecordingView.ts's `PlotRecording`.
 * Must not import lib/plots/plotting.ts, Plotly or React.
 */
import { RING_WINDOW_MAX_MS } from "./plots";
import type { PlotView } from "./plotRecordingView";

/** The view of a picked window: the ring up to 2 min, a moving view of the recording beyond (when it has one). */
export function viewForWindow(reachesRecording: boolean, window_ms: number): PlotView {
  return reachesRecording && window_ms > RING_WINDOW_MAX_MS ? { kind: "moving", span_ms: window_ms } : { kind: "ring" };
}

/**
 * What a moving window's due refresh does: "ask" the recording now; "later": only schedule the
 * next turn (out of view: the plot asks again within a turn of coming into view); "none": no
 * longer a moving window, or paused (frozen until resumed, which goes back to live and asks).
 */
export function refreshAction(view: PlotView["kind"], paused: boolean, onScreen: boolean): "ask" | "later" | "none" {
  if (view !== "moving" || paused) return "none";
  return onScreen ? "ask" : "later";
}
