/**
 * Layer: plain TypeScript (no React, no DOM, no Plotly). The panel's shared time range: a
 * click on an event marker of one plot moves every plot of the panel (the fixed and custom
 * live plots alike) to the same range of the past, so the joints, the TCP and the forces of an
 * incident are seen side by side; "Back to live" on a plot still showing that range brings back
 * every plot still showing it (a plot moved on from it since keeps its own range)
 * (docs/architecture.md "Plots: from the ring into the recording").
 */
import type { TimeRange } from "./historyView";

/** A jump to `range`, or the way back to live from it. */
export type SharedTimeEvent = { readonly kind: "jump"; readonly range: TimeRange } | { readonly kind: "live"; readonly range: TimeRange };

type Listener = (event: SharedTimeEvent) => void;

export class PlotTimeRange {
  private readonly listeners = new Set<Listener>();
  private shown: TimeRange | null = null;

  /** The range of the last jump, or null before any and after the way back to live. */
  get current(): TimeRange | null {
    return this.shown;
  }

  /** Every listening plot shows `range` (a fixed range of the past). */
  jumpTo(range: TimeRange): void {
    if (!(range.to_s > range.from_s)) return;
    this.shown = range;
    this.tell({ kind: "jump", range });
  }

  /** Every listening plot still on the last jump's range goes back to live. */
  backToLive(): void {
    const range = this.shown;
    if (range === null) return;
    this.shown = null;
    this.tell({ kind: "live", range });
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

  private tell(event: SharedTimeEvent): void {
    for (const listener of [...this.listeners]) listener(event);
  }
}
