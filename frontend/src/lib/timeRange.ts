/**
 * Layer: plain TypeScript (no React, no DOM, no Plotly). The panel's shared time range: a
 * click on an event marker of one plot moves every plot of the panel (the fixed and custom
 * live plots alike) to the same range of the past, so the joints, the TCP and the forces of an
 * incident are seen side by side. Each plot listens while it is mounted; "Back to live" is the
 * plot's own (docs/architecture.md "Plots: from the ring into the recording").
 */
import { rangeAround, type TimeRange } from "./historyView";

type Listener = (range: TimeRange) => void;

export class PlotTimeRange {
  private readonly listeners = new Set<Listener>();
  private shown: TimeRange | null = null;

  /** The range of the last jump, or null before any. */
  get current(): TimeRange | null {
    return this.shown;
  }

  /** Every listening plot shows `range` (a fixed range of the past). */
  jumpTo(range: TimeRange): void {
    if (!(range.to_s > range.from_s)) return;
    this.shown = range;
    for (const listener of [...this.listeners]) listener(range);
  }

  /** Every listening plot shows `span_s` around `time_s` (a marker's moment at the centre). */
  jumpAround(time_s: number, span_s = 60): void {
    this.jumpTo(rangeAround(time_s, span_s));
  }

  /** Listen; the function returned stops listening. */
  subscribe(listener: Listener): () => void {
    this.listeners.add(listener);
    return () => {
      this.listeners.delete(listener);
    };
  }

  get listenerCount(): number {
    return this.listeners.size;
  }
}
