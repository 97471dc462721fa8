/**
 * Layer: what a live plot asks of Plotly (plain TypeScript). lib/plots/plotlyAdapter.ts implements it
 * over Plotly, the tests with a recording fake; lib/plots/plotting.ts never imports Plotly itself.
 */
type Datum = number | null;

export interface PlotBackend {
  /**
   * Whether Plotly has come (lib/plots/plotlyAdapter.ts loads it on first need); absent: always (the
   * tests' fakes). No drawing call is made before.
   */
  ready?(): boolean;
  /** Load Plotly (once; again after a failure); resolves when `ready()`. */
  load?(): Promise<void>;
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

/** What a static picture of a ring view draws besides its points. */
export interface PictureDrawing {
  /** The signal picker's choice per trace. */
  readonly visible: readonly boolean[];
  /** The x range (numeric dates, as the points); null: the points' own (Plotly's autorange). */
  readonly x: readonly [number, number] | null;
  /** A y axis' range by Plotly's axis name ("yaxis", "yaxis2"); absent: autoranged. */
  readonly y: Readonly<Partial<Record<"yaxis" | "yaxis2", readonly [number, number]>>>;
}

/**
 * A live plot's static picture (plots/canvasPlot.ts): the ring view's points drawn without
 * Plotly while nobody points at the plot. It holds the points as Plotly's traces would.
 */
export interface StaticPicture {
  /** Replace every trace's points. */
  reset(xs: readonly number[][], ys: readonly Datum[][]): void;
  /** Append points, keeping each trace's newest `maxPoints`. */
  extend(xs: readonly number[][], ys: readonly Datum[][], maxPoints: number): void;
  /** Draw the points held; the x range drawn (numeric dates), or null when nothing was. */
  draw(drawing: PictureDrawing): readonly [number, number] | null;
  /** Shown over Plotly's plot (true), or hidden for it. */
  show(on: boolean): void;
  /** Save the picture as drawn now as `filename`.png. */
  savePng?(filename: string): void;
}
