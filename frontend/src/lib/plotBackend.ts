/**
 * Layer: what a live plot asks of Plotly (plain TypeScript). lib/plotlyAdapter.ts implements it
 * over Plotly, the tests with a recording fake; lib/plotting.ts never imports Plotly itself.
 */
type Datum = number | null;

export interface PlotBackend {
  newPlot(el: HTMLElement, data: object[], layout: object, config: object): void;
  react(el: HTMLElement, data: object[], layout: object, config: object): void;
  /**
   * Append points to traces; `axes`: axis attributes (e.g. a live plot's time ticks) to change
   * in the same redraw.
   */
  extendTraces(
    el: HTMLElement,
    update: { x: Datum[][]; y: Datum[][] },
    indices: number[],
    maxPoints: number,
    axes?: Readonly<Record<string, object>>,
  ): void;
  restyle(el: HTMLElement, update: object, indices: number[]): void;
  relayout(el: HTMLElement, update: object): void;
  /** The axes a person zoomed or panned (autorange off) and their ranges now. */
  zoomedAxes(el: HTMLElement): Readonly<Record<string, readonly unknown[]>>;
  /** Call `listener` after each zoom, pan or autoscale a person makes (Plotly's relayout). */
  onRelayout?(el: HTMLElement, listener: () => void): void;
  /** Save the plot as it is drawn now as a PNG file. */
  downloadPng?(el: HTMLElement, filename: string): void;
  purge(el: HTMLElement): void;
}
