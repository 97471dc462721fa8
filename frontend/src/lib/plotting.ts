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
import { axisTitle, tracesOf, type PlotSpec, type TraceInfo } from "./plots";
import type { SampleRing } from "./ringBuffer";
import type { ChannelMap } from "./plots";

type Datum = number | null;

export interface PlotBackend {
  newPlot(el: HTMLElement, data: object[], layout: object, config: object): void;
  react(el: HTMLElement, data: object[], layout: object, config: object): void;
  extendTraces(el: HTMLElement, update: { x: Datum[][]; y: Datum[][] }, indices: number[], maxPoints: number): void;
  restyle(el: HTMLElement, update: object, indices: number[]): void;
  purge(el: HTMLElement): void;
}

/** Buckets per window: two points each, so a trace holds at most 800 points in any window. */
export const BUCKETS_PER_WINDOW = 400;

export type PlotTheme = "light" | "dark";

export interface LivePlotOptions {
  readonly window_ms: number;
  readonly theme: PlotTheme;
  /** Kiosk: a static picture, no zoom, no mode bar, no hover. */
  readonly readOnly: boolean;
  readonly height_px?: number;
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
  private visible: boolean[];
  private tzShift_ms = 0;
  private revision = 0;
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
    this.needsRebuild = true;
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
    this.paused = paused;
    // Resuming redraws the whole window from the ring, which kept buffering meanwhile.
    if (!paused) this.needsRebuild = true;
    this.mark();
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
    this.backend.react(el, data, this.layout(), this.config());
    this.updates++;
    this.mark();
  }

  private mark(): void {
    if (this.el === null) return;
    this.el.dataset.points = String(this.points);
    this.el.dataset.paused = this.paused ? "true" : "false";
    this.el.dataset.windowMs = String(this.window_ms);
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
      hoverinfo: this.options.readOnly ? "skip" : "x+y+name",
    };
  }

  private layout(): object {
    const dark = this.options.theme === "dark";
    const fg = dark ? "#d8dde3" : "#222";
    const grid = dark ? "#2f3740" : "#e3e3e3";
    const twoAxes = this.spec.series.some((s) => s.axis === "y2");
    const y1 = this.spec.series.find((s) => s.axis === "y");
    const y2 = this.spec.series.find((s) => s.axis === "y2");
    const layout: Record<string, unknown> = {
      uirevision: `${this.spec.id}:${this.revision}`,
      autosize: true,
      height: this.options.height_px ?? 240,
      margin: { l: 64, r: twoAxes ? 64 : 16, t: 8, b: 36 },
      showlegend: false,
      paper_bgcolor: dark ? "#12161b" : "#ffffff",
      plot_bgcolor: dark ? "#12161b" : "#ffffff",
      font: { color: fg, size: 11 },
      hovermode: this.options.readOnly ? false : "x",
      xaxis: { type: "date", autorange: true, gridcolor: grid },
      yaxis: {
        autorange: true,
        gridcolor: grid,
        zeroline: false,
        title: { text: y1 === undefined ? "" : axisTitle(y1) },
      },
    };
    if (y2 !== undefined) {
      layout.yaxis2 = {
        autorange: true,
        overlaying: "y",
        side: "right",
        zeroline: false,
        showgrid: false,
        title: { text: axisTitle(y2) },
      };
    }
    return layout;
  }

  private config(): object {
    if (this.options.readOnly) {
      return { staticPlot: true, displayModeBar: false, responsive: true };
    }
    return {
      responsive: true,
      displaylogo: false,
      modeBarButtonsToRemove: ["select2d", "lasso2d", "toImage"],
    };
  }
}

/** Time source and frame scheduler of the coordinator (the browser's, or a test's). */
export interface FrameScheduler {
  now(): number;
  request(callback: () => void): number;
  cancel(handle: number): void;
}

export const browserScheduler: FrameScheduler = {
  now: () => performance.now(),
  request: (cb) => requestAnimationFrame(() => cb()),
  cancel: (h) => cancelAnimationFrame(h),
};

export class PlotCoordinator {
  private readonly plots: LivePlot[] = [];
  private readonly scheduler: FrameScheduler;
  private handle: number | null = null;
  private next = 0;
  /** Work per animation frame before the remaining plots wait for the next one. */
  budget_ms = 10;
  /** Plots out of view are refreshed this often. */
  offscreenInterval_ms = 1000;
  ticks = 0;
  plotUpdates = 0;

  constructor(scheduler: FrameScheduler = browserScheduler) {
    this.scheduler = scheduler;
  }

  add(plot: LivePlot): void {
    if (!this.plots.includes(plot)) this.plots.push(plot);
  }

  remove(plot: LivePlot): void {
    const i = this.plots.indexOf(plot);
    if (i >= 0) this.plots.splice(i, 1);
  }

  start(): void {
    if (this.handle !== null) return;
    const loop = () => {
      this.handle = this.scheduler.request(loop);
      this.tick();
    };
    this.handle = this.scheduler.request(loop);
  }

  stop(): void {
    if (this.handle !== null) this.scheduler.cancel(this.handle);
    this.handle = null;
  }

  /** One animation frame: update plots round-robin until the budget is spent. */
  tick(): void {
    this.ticks++;
    const n = this.plots.length;
    if (n === 0) return;
    const start = this.scheduler.now();
    for (let k = 0; k < n; k++) {
      const index = (this.next + k) % n;
      const plot = this.plots[index] as LivePlot;
      if (!plot.hasWork()) continue;
      const now = this.scheduler.now();
      if (!plot.onScreen && now - plot.lastUpdate_ms < this.offscreenInterval_ms) continue;
      if (plot.update(now)) this.plotUpdates++;
      if (this.scheduler.now() - start >= this.budget_ms) {
        this.next = (index + 1) % n;
        return;
      }
    }
  }
}
