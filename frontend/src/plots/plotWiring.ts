/**
 * Layer: DOM glue of one live plot of the panel (no React, no Plotly): what
 * components/LivePlotView.tsx attaches to a `LivePlot` once it is mounted.
 *
 * - The panel's one time axis (lib/plots/timeRange.ts): the plot linked (its moves reach every linked
 *   plot, it follows theirs) or unlinked, at the person's choice.
 * - The one cursor: the time under the pointer (or moved by Shift + ← / →) on any linked plot,
 *   shown with every linked plot's values (plots/cursorReadout.ts); an unlinked plot has its own.
 * - The mouse wheel with Ctrl (or ⌘) held zooms the time axis around the time under the pointer
 *   (lib/plots/plotSteps.ts `zoomAround`); the wheel alone scrolls the page as ever (a panel of plots
 *   under a wheel would otherwise never scroll).
 */
import { hasSecondAxis, plotMargin, type PlotMargin } from "../lib/plots/plotAppearance";
import type { LivePlot } from "../lib/plots/plotting";
import { linkPlot, type PlotTimeRange } from "../lib/plots/timeRange";
import { CursorReadout } from "./cursorReadout";
import { cursorAfterKey, timeAtPixel, wheelFactor } from "./plotPointer";

export interface PlotElements {
  /** Plotly's element, the plotting area. */
  readonly area: HTMLElement;
  readonly cursorOut: HTMLElement;
  readonly cursorLine: HTMLElement;
}

export class PlotWiring {
  private readonly plot: LivePlot;
  private readonly els: PlotElements;
  private readonly axis: PlotTimeRange | null;
  private readonly margin: PlotMargin;
  private readonly readout: CursorReadout;
  private unlink: (() => void) | null = null;
  private stopCursor: (() => void) | null = null;
  private readonly cleanups: (() => void)[] = [];

  constructor(plot: LivePlot, els: PlotElements, axis: PlotTimeRange | null, linked: boolean) {
    this.plot = plot;
    this.els = els;
    this.axis = axis;
    this.margin = plotMargin(hasSecondAxis(plot.spec));
    this.readout = new CursorReadout(els.cursorOut, els.cursorLine, plot, plot.traces, this.margin, plot.spec.id);
    plot.onDrawn = () => {
      if (this.readout.time !== null) this.readout.refresh();
    };
    this.setLinked(linked);
    this.listen("pointermove", (e) => this.pointAt((e as PointerEvent).clientX));
    this.listen("pointerleave", () => this.setCursor(null));
    this.listen("blur", () => this.setCursor(null));
    this.listen("wheel", (e) => this.wheel(e as WheelEvent), { passive: false });
  }

  private listen(type: string, handler: (e: Event) => void, options?: AddEventListenerOptions): void {
    this.els.area.addEventListener(type, handler, options);
    this.cleanups.push(() => this.els.area.removeEventListener(type, handler, options));
  }

  /** Link the plot to the panel's time axis and cursor (true), or give it its own (false). */
  setLinked(linked: boolean): void {
    this.unlink?.();
    this.stopCursor?.();
    this.unlink = null;
    this.stopCursor = null;
    if (linked && this.axis !== null) {
      this.unlink = linkPlot(this.axis, this.plot);
      this.stopCursor = this.axis.subscribeCursor((t) => this.readout.show(t));
      this.readout.show(this.axis.cursorTime);
    } else this.readout.show(null);
  }

  private get linked(): boolean {
    return this.unlink !== null;
  }

  /** The cursor at `time_ms` (null: none): the panel's when linked, else this plot's own. */
  private setCursor(time_ms: number | null): void {
    if (this.linked && this.axis !== null) this.axis.setCursor(time_ms);
    else this.readout.show(time_ms);
  }

  private timeAt(clientX: number): number | null {
    const box = this.els.area.getBoundingClientRect();
    return timeAtPixel(clientX - box.left, box.width, this.margin, this.plot.shownRange());
  }

  private pointAt(clientX: number): void {
    this.setCursor(this.timeAt(clientX));
  }

  /** Shift + ← / → on the focused plotting area: the cursor a step earlier or later. */
  cursorKey(direction: -1 | 1): void {
    this.setCursor(cursorAfterKey(this.readout.time, direction, this.plot.shownRange()));
  }

  private wheel(e: WheelEvent): void {
    if (!(e.ctrlKey || e.metaKey)) return;
    const at = this.timeAt(e.clientX);
    if (at === null) return;
    // Not the browser's page zoom (Ctrl + wheel's default).
    e.preventDefault();
    this.plot.zoomAt(at, wheelFactor(e.deltaY, e.deltaMode));
  }

  dispose(): void {
    this.unlink?.();
    this.stopCursor?.();
    for (const cleanup of this.cleanups) cleanup();
    this.plot.onDrawn = null;
  }
}
