/**
 * Layer: plain TypeScript (no React, no DOM). The way from a live plot into the history plot:
 * a live plot asks for its range of the past ("History" after a zoom or a pause), the panel's
 * history view listens and shows that plot over that range (docs/architecture.md "History plot").
 */
import type { TimeRange } from "./historyView";

export interface HistoryRequest {
  /** The live plot's PlotSpec id: the history view shows the same fields. */
  readonly specId: string;
  readonly range: TimeRange;
}

type Listener = (request: HistoryRequest) => void;

export class HistoryLink {
  private readonly listeners = new Set<Listener>();

  /** Ask the listening history view to show `request`; false when none listens. */
  show(request: HistoryRequest): boolean {
    for (const listener of this.listeners) listener(request);
    return this.listeners.size > 0;
  }

  /** Listen; the function returned stops listening. */
  listen(listener: Listener): () => void {
    this.listeners.add(listener);
    return () => {
      this.listeners.delete(listener);
    };
  }
}

/** The page's link (one panel, one history view). */
export const historyLink = new HistoryLink();
