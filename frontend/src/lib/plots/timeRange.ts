/**
 * Layer: plain TypeScript (no React, no DOM, no Plotly). The panel's one time axis
 * (docs/architecture.md "Plots: one time axis for the panel").
 *
 * Every plot of the panel (the fixed and the custom ones) listens, and each move a person makes
 * on one plot reaches all the others that are linked: a zoom or pan to a range (each takes the
 * same decision as its own zoom: a zoom of its ring, or a range of the recording), a window
 * picked, back to live, a jump to a range of the past (a marker's click or a custom range,
 * fetched at once). A plot can be unlinked: it then neither tells nor follows. The same axis
 * carries the panel's cursor: the time the pointer (or the arrow keys) points at on any plot,
 * at which every plot shows its values.
 */
import type { TimeRange } from "./historyView";

/** A move of the time axis a person made on one plot. */
export type PlotMove =
  | { readonly kind: "range"; readonly range: TimeRange }
  | { readonly kind: "window"; readonly window_ms: number }
  | { readonly kind: "live" }
  | { readonly kind: "jump"; readonly range: TimeRange };

type MoveListener = (move: PlotMove) => void;
type CursorListener = (time_ms: number | null) => void;

export class PlotTimeRange {
  private readonly listeners = new Map<object, MoveListener>();
  private readonly cursorListeners = new Set<CursorListener>();
  private shown: TimeRange | null = null;
  private cursor: number | null = null;
  private opening: TimeRange | null = null;

  /**
   * The panel opens at `range` (its URL's `from`/`to`, lib/common/route.ts): a jump there, which
   * every plot that links while the axis still shows it follows at once as it links (the plots
   * come after the axis). Null: the panel opens live.
   */
  openAt(range: TimeRange | null): this {
    if (range === null || !(range.to_s > range.from_s)) return this;
    this.opening = range;
    this.jumpTo(range);
    return this;
  }

  /** The range of the last jump, or null before any and after the way back to live. */
  get current(): TimeRange | null {
    return this.shown;
  }

  /**
   * Tell every listening plot but `source` (the plot the person moved, which has moved already).
   * A range or a jump that is no range reaches none.
   */
  move(move: PlotMove, source: object | null = null): void {
    if ((move.kind === "range" || move.kind === "jump") && !(move.range.to_s > move.range.from_s)) return;
    if (move.kind === "jump") this.shown = move.range;
    else if (move.kind === "live") this.shown = null;
    else if (move.kind === "range") this.shown = null;
    for (const [key, listener] of [...this.listeners]) if (key !== source) listener(move);
  }

  /** Every listening plot shows `range` (a fixed range of the past), fetched at once. */
  jumpTo(range: TimeRange): void {
    this.move({ kind: "jump", range });
  }

  /** Every listening plot goes back to live. */
  backToLive(): void {
    this.move({ kind: "live" });
  }

  /** Listen as `key` (a plot's own moves are not told back to it); the function returned stops. */
  subscribe(listener: MoveListener, key: object = {}): () => void {
    this.listeners.set(key, listener);
    if (this.opening !== null && this.shown === this.opening) listener({ kind: "jump", range: this.opening });
    return () => {
      this.listeners.delete(key);
    };
  }

  get listenerCount(): number {
    return this.listeners.size;
  }

  /** The cursor's time (ms since the epoch), or null while no plot is pointed at. */
  get cursorTime(): number | null {
    return this.cursor;
  }

  /** Put the cursor at `time_ms` (null: take it away); every cursor listener is told. */
  setCursor(time_ms: number | null): void {
    const next = time_ms !== null && Number.isFinite(time_ms) ? time_ms : null;
    if (next === this.cursor) return;
    this.cursor = next;
    for (const listener of [...this.cursorListeners]) listener(next);
  }

  subscribeCursor(listener: CursorListener): () => void {
    this.cursorListeners.add(listener);
    return () => {
      this.cursorListeners.delete(listener);
    };
  }
}

/** A plot as the time axis links it (lib/plots/plotting.ts `LivePlot`). */
export interface LinkedPlot {
  onMove: ((move: PlotMove) => void) | null;
  follow(move: PlotMove): void;
}

/**
 * Link `plot` to the panel's time axis: its moves are told to every other linked plot, and it
 * follows theirs. The function returned unlinks it (a plot's "Linked" setting off).
 */
export function linkPlot(axis: PlotTimeRange, plot: LinkedPlot): () => void {
  plot.onMove = (move) => axis.move(move, plot);
  const stop = axis.subscribe((move) => plot.follow(move), plot);
  return () => {
    stop();
    plot.onMove = null;
  };
}
