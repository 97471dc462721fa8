/**
 * Layer: live plots over the sample ring, independent of React (plain TypeScript).
 *
 * Lichtblick-style: the WebSocket fills the ring; one `requestAnimationFrame` loop (the
 * coordinator) asks each plot to append what arrived since its last update with `extendTraces`,
 * within a time budget per animation frame and round-robin, so the page keeps rendering smoothly
 * however many plots there are; a plot scrolled out of view refreshes only about once a second.
 * Each plot is created once; it is rebuilt (`react`) only when its window changes, when it is
 * resumed after a pause (the ring kept buffering meanwhile) or when it fell behind the ring.
 * `uirevision` keeps the person's zoom while data streams. Plotly itself is reached through the
 * small `PlotBackend` interface (src/lib/plotlyAdapter.ts in the app, a fake in tests).
 */
import { bucketWidthMs, MinMaxBucketer, POINTS_PER_BUCKET } from "./decimate";
import { tracesOf, type PlotSpec, type TraceInfo } from "./plots";
import type { SampleRing } from "./ringBuffer";
import type { ChannelMap } from "./plots";

type Datum = number | null;

export interface PlotBackend {
  newPlot(el: HTMLElement, data: object[], layout: object, config: object): void;
  react(el: HTMLElement, data: object[], layout: object, config: object): void;
  extendTraces(el: HTMLElement, update: { x: Datum[][]; y: Datum[][] }, indices: number[], maxPoints: number): void;
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

/** Buckets per window: two points each, so a trace holds at most 600 points in any window. */
export const BUCKETS_PER_WINDOW = 300;

export const DEFAULT_PLOT_HEIGHT_PX = 240;

/** Plot margins (px) around the plotting area; the view places the axis titles in them. */
export interface PlotMargin {
  readonly l: number;
  readonly r: number;
  readonly t: number;
  readonly b: number;
}

export function plotMargin(twoAxes: boolean): PlotMargin {
  return { l: 64, r: twoAxes ? 64 : 16, t: 8, b: 36 };
}

export type PlotTheme = "light" | "dark";

export interface LivePlotOptions {
  readonly window_ms: number;
  readonly theme: PlotTheme;
  /** Kiosk: a static picture, no zoom, no mode bar, no hover. */
  readonly readOnly: boolean;
  readonly height_px?: number;
  /** Tick labels' size (px); the kiosk's are large (no text under 18 px there). */
  readonly fontSize_px?: number;
}

/** Trace colours (colour-blind friendly order, Okabe–Ito). */
export const TRACE_COLOURS: readonly string[] = [
  "#0072B2",
  "#E69F00",
  "#009E73",
  "#CC79A7",
  "#56B4E9",
  "#D55E00",
];

export function traceColour(i: number): string {
  return TRACE_COLOURS[i % TRACE_COLOURS.length] as string;
}

export class LivePlot {
  readonly spec: PlotSpec;
  readonly traces: readonly TraceInfo[];
  private readonly ring: SampleRing;
  private readonly ringChannels: number[];
  private readonly backend: PlotBackend;
  private readonly options: LivePlotOptions;
  private el: HTMLElement | null = null;
  private window_ms: number;
  private bucketer: MinMaxBucketer;
  private readSeq = 0;
  private needsRebuild = true;
  private paused = false;
  private pointerInside = false;
  private visible: boolean[];
  private tzShift_ms = 0;
  private revision = 0;
  private zoomed = false;
  /** Told when the plot is zoomed away from the moving window, or back on it. */
  onZoomedChange: ((zoomed: boolean) => void) | null = null;
  /** `revision` of the last drawing: a rebuild within the same revision keeps the zoom. */
  private drawnRevision = -1;
  /** Points in each trace now (all traces have the same count). */
  points = 0;
  /** Browser time of the last update (performance.now()). */
  lastUpdate_ms = -Infinity;
  /** Whether the element is in the viewport (the coordinator updates others less often). */
  onScreen = true;
  updates = 0;

  constructor(spec: PlotSpec, ring: SampleRing, channels: ChannelMap, backend: PlotBackend, options: LivePlotOptions) {
    this.spec = spec;
    this.traces = tracesOf(spec);
    this.ring = ring;
    this.ringChannels = this.traces.map((t) => channels.channelOf(t.fieldName, t.channel));
    this.backend = backend;
    this.options = options;
    this.window_ms = options.window_ms;
    this.visible = this.traces.map(() => true);
    this.bucketer = this.newBucketer();
  }

  get maxPoints(): number {
    return BUCKETS_PER_WINDOW * POINTS_PER_BUCKET;
  }

  get isPaused(): boolean {
    return this.paused;
  }

  get windowMs(): number {
    return this.window_ms;
  }

  /** Create the Plotly plot in `el` (once). */
  mount(el: HTMLElement): void {
    this.el = el;
    this.backend.newPlot(el, this.emptyData(), this.layout(), this.config());
    this.backend.onRelayout?.(el, () => this.checkZoom());
    this.needsRebuild = true;
  }

  /** Whether a person zoomed or panned the plot away from its moving window. */
  get isZoomed(): boolean {
    return this.zoomed;
  }

  private checkZoom(): void {
    if (this.el === null) return;
    this.setZoomed(Object.keys(this.backend.zoomedAxes(this.el)).length > 0);
  }

  private setZoomed(zoomed: boolean): void {
    if (zoomed === this.zoomed) return;
    this.zoomed = zoomed;
    this.mark();
    this.onZoomedChange?.(zoomed);
  }

  /**
   * Back to the moving window: unpaused, every axis autoranged again (a zoom is dropped with a
   * new `uirevision`), the whole window redrawn from the ring at once.
   */
  backToLive(): void {
    this.paused = false;
    this.revision++;
    this.setZoomed(false);
    this.needsRebuild = true;
    if (this.el !== null) this.rebuild(this.el);
    this.mark();
  }

  /** Save the plot as drawn now as `filename`.png. */
  exportPng(filename: string): void {
    if (this.el !== null) this.backend.downloadPng?.(this.el, filename);
  }

  unmount(): void {
    if (this.el !== null) this.backend.purge(this.el);
    this.el = null;
  }

  setWindow(window_ms: number): void {
    if (window_ms === this.window_ms) return;
    this.window_ms = window_ms;
    this.revision++; // a new window length starts from autorange, not the old zoom
    this.needsRebuild = true;
  }

  setPaused(paused: boolean): void {
    if (paused === this.paused) return;
    if (!paused) {
      // Resuming is going back to live: the moving window, not a zoom into a time now past
      // (with it the plot would scroll out of the range and go blank).
      this.backToLive();
      return;
    }
    this.paused = true;
    // Pausing redraws once, interactive with hover (see `interactive`), frozen from then on.
    if (this.el !== null) this.rebuild(this.el);
    this.mark();
  }

  /**
   * The pointer entered or left the plot. A live plot is a static picture (no zoom layer, no
   * hover) while nobody points at it — a Plotly redraw costs markedly less so — and becomes
   * interactive as soon as the pointer is on it, so a person can zoom while data streams;
   * `uirevision` keeps that zoom when it turns static again.
   */
  setPointerInside(inside: boolean): void {
    if (inside === this.pointerInside) return;
    const before = this.interactive;
    this.pointerInside = inside;
    // At once, not at the next tick: the person may start dragging a zoom box right away.
    if (this.interactive !== before && !this.paused && this.el !== null) this.rebuild(this.el);
  }

  /** Interactive (zoom, pan, mode bar; hover too when paused), or a static picture. */
  get interactive(): boolean {
    return !this.options.readOnly && (this.paused || this.pointerInside);
  }

  setTraceVisible(index: number, visible: boolean): void {
    if (this.visible[index] === undefined || this.visible[index] === visible) return;
    this.visible[index] = visible;
    if (this.el !== null) this.backend.restyle(this.el, { visible }, [index]);
  }

  isTraceVisible(index: number): boolean {
    return this.visible[index] ?? false;
  }

  /** Whether an update would do anything now. */
  hasWork(): boolean {
    if (this.el === null || this.paused) return false;
    return this.needsRebuild || this.readSeq !== this.ring.endSeq;
  }

  /** Append what arrived since the last update (or rebuild); true if Plotly was called. */
  update(now_ms: number): boolean {
    const el = this.el;
    if (el === null || this.paused) return false;
    if (this.needsRebuild || this.readSeq < this.ring.oldestSeq) {
      this.rebuild(el);
      this.lastUpdate_ms = now_ms;
      return true;
    }
    const end = this.ring.endSeq;
    if (this.readSeq === end) return false;
    this.bucketer.feedRing(this.ring, this.readSeq, end);
    this.readSeq = end;
    const chunk = this.bucketer.take();
    if (chunk === null) return false;
    const indices = this.traces.map((_, i) => i);
    this.backend.extendTraces(el, { x: chunk.xs, y: chunk.ys }, indices, this.maxPoints);
    this.points = Math.min(this.maxPoints, this.points + chunk.buckets * POINTS_PER_BUCKET);
    this.lastUpdate_ms = now_ms;
    this.updates++;
    this.mark();
    return true;
  }

  private rebuild(el: HTMLElement): void {
    this.needsRebuild = false;
    this.tzShift_ms = new Date().getTimezoneOffset() * 60_000;
    this.bucketer = this.newBucketer();
    const newest = this.ring.newestTime();
    const end = this.ring.endSeq;
    if (newest !== null) {
      const from = this.ring.firstSeqAtOrAfter(newest - this.window_ms);
      this.bucketer.feedRing(this.ring, from, end);
    }
    this.readSeq = end;
    const chunk = this.bucketer.take();
    const data = this.traces.map((trace, i) => ({
      ...this.traceStyle(trace, i),
      x: chunk?.xs[i] ?? [],
      y: chunk?.ys[i] ?? [],
    }));
    this.points = Math.min(this.maxPoints, (chunk?.buckets ?? 0) * POINTS_PER_BUCKET);
    // `uirevision` keeps a zoom across a redraw, but not across a change of config (Plotly
    // starts over then, as when the plot turns static or interactive): carry it explicitly.
    const zoom = this.drawnRevision === this.revision ? this.backend.zoomedAxes(el) : {};
    this.drawnRevision = this.revision;
    this.backend.react(el, data, this.layout(zoom), this.config());
    this.updates++;
    this.mark();
  }

  private mark(): void {
    if (this.el === null) return;
    this.el.dataset.points = String(this.points);
    this.el.dataset.paused = this.paused ? "true" : "false";
    this.el.dataset.windowMs = String(this.window_ms);
    this.el.dataset.interactive = this.interactive ? "true" : "false";
    this.el.dataset.zoomed = this.zoomed ? "true" : "false";
  }

  private newBucketer(): MinMaxBucketer {
    return new MinMaxBucketer(
      this.ringChannels,
      bucketWidthMs(this.window_ms, BUCKETS_PER_WINDOW),
      BUCKETS_PER_WINDOW,
      // Plotly shows numeric dates in UTC: shift to the browser's local time of day.
      (t) => t - this.tzShift_ms,
    );
  }

  private emptyData(): object[] {
    return this.traces.map((trace, i) => ({ ...this.traceStyle(trace, i), x: [], y: [] }));
  }

  private traceStyle(trace: TraceInfo, i: number): object {
    return {
      type: "scatter",
      mode: "lines",
      name: trace.name,
      yaxis: trace.axis,
      visible: this.visible[i] ?? true,
      line: { width: 1.5, color: traceColour(i), dash: trace.axis === "y2" ? "dot" : "solid" },
      connectgaps: false,
      // The value with the layout's unit ("J 1: 12.35 degree"), the time in the hover's header.
      ...(this.options.readOnly
        ? { hoverinfo: "skip" }
        : { hovertemplate: `${trace.name}: %{y:.4~r} ${trace.field.unit}<extra></extra>` }),
      hoverlabel: { namelength: -1 },
    };
  }

  private layout(zoom: Readonly<Record<string, readonly unknown[]>> = {}): object {
    const dark = this.options.theme === "dark";
    const fg = dark ? "#d8dde3" : "#222";
    const grid = dark ? "#2f3740" : "#e3e3e3";
    const twoAxes = this.spec.series.some((s) => s.axis === "y2");
    const layout: Record<string, unknown> = {
      uirevision: `${this.spec.id}:${this.revision}`,
      autosize: true,
      height: this.options.height_px ?? DEFAULT_PLOT_HEIGHT_PX,
      margin: plotMargin(twoAxes),
      showlegend: false,
      paper_bgcolor: dark ? "#12161b" : "#ffffff",
      plot_bgcolor: dark ? "#12161b" : "#ffffff",
      font: { color: fg, size: this.options.fontSize_px ?? 11 },
      // Hover whenever the plot is interactive (the pointer on it, or paused): live too.
      hovermode: this.interactive ? "x" : false,
      // No Plotly axis titles: the view draws them (axisTitles in plots.ts) beside the plot. With a
      // title, Plotly measures every tick label against it on every redraw and caches each
      // measurement under the label's pixel position: with autoranged axes the labels keep
      // moving, and its text-measurement cache grew by hundreds of entries a minute.
      // "allow": Plotly otherwise measures every tick label on every redraw (a quarter of its time).
      xaxis: { type: "date", autorange: true, gridcolor: grid, ticklabeloverflow: "allow" },
      yaxis: {
        autorange: true,
        gridcolor: grid,
        zeroline: false,
        ticklabeloverflow: "allow",
      },
    };
    if (twoAxes) {
      layout.yaxis2 = {
        autorange: true,
        overlaying: "y",
        side: "right",
        zeroline: false,
        showgrid: false,
        ticklabeloverflow: "allow",
      };
    }
    for (const [axis, range] of Object.entries(zoom)) {
      const current = layout[axis];
      if (typeof current === "object" && current !== null) {
        layout[axis] = { ...current, autorange: false, range: [...range] };
      }
    }
    return layout;
  }

  private config(): object {
    if (!this.interactive) {
      return { staticPlot: true, displayModeBar: false, responsive: true };
    }
    return {
      responsive: true,
      displaylogo: false,
      modeBarButtonsToRemove: ["select2d", "lasso2d", "toImage"],
    };
  }
}
