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
 *
 * A plot of the panel also reaches the recording (docs/architecture.md "Plots: from the ring
 * into the recording"). Its view is one of three: "ring" (a window of up to 2 min, drawn from the
 * ring alone, never fetching), "moving" (a long window, 15 min … 7 days: the history API's
 * decimated range, refreshed as it moves, the newest seconds from the ring) or "fixed" (a range
 * of the past: a zoom or pan reaching before what the ring holds, a marker's jump, a custom
 * range). A history view fetches through a `RangeLoader` (debounced, a stale answer dropped) and
 * draws only when an answer arrives: in between `hasWork()` is false and a frame costs nothing.
 */
import { bucketWidthMs, MinMaxBucketer, POINTS_PER_BUCKET } from "./decimate";
import {
  RangeLoader,
  axisTimeToEpochS,
  browserTimer,
  bucketsForWidth,
  envelopeTraceSets,
  markersOf,
  newestRecorded,
  type FetchRange,
  type HistoryEvent,
  type RangeData,
  type TimeRange,
  type Timer,
} from "./historyView";
import { RING_WINDOW_MAX_MS, traceColour, tracesOf, type PlotSpec, type TraceInfo } from "./plots";
import { stepRange, type PlotStep, type SpanMs } from "./plotSteps";
import type { SampleRing } from "./ringBuffer";
import { TICK_SPACING_PX, timeTicks, type TimeTicks } from "./timeTicks";
import type { ChannelMap } from "./plots";

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

/**
 * Buckets per window: two points each, so a trace holds at most 400 points in any window, about
 * one per pixel of a plot on a 1920 px panel (three plots abreast). A redraw's time grows with
 * the points (Plotly's path building, the browser's path parsing and rasterising): 600 points
 * cost about a third more for nothing the eye sees.
 */
export const BUCKETS_PER_WINDOW = 200;

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
  /** The plot's way into the recording (the panel's plots); none: the ring only (the kiosk). */
  readonly history?: PlotHistorySource;
}

/** Where a plot reads the recording of its fields (lib/historyApi.ts in the panel, a fake in tests). */
export interface PlotHistorySource {
  readonly fetchRange: FetchRange;
  /** Requests while a person moves the view wait this long for the view to settle (ms). */
  readonly debounce_ms?: number;
  readonly timer?: Timer;
  /** The time now (ms since the epoch), when the ring has no recent frame to tell it. */
  readonly now_ms?: () => number;
}

/**
 * What a plot shows: its moving window from the ring; a long moving window from the recording
 * (and the ring's newest seconds); or a fixed range of the past (times in ms since the epoch).
 */
export type PlotView =
  | { readonly kind: "ring" }
  | { readonly kind: "moving"; readonly span_ms: number }
  | { readonly kind: "fixed"; readonly from_ms: number; readonly to_ms: number };

/** What a plot showing the recording tells its view (markers, range, export links, errors). */
export interface HistoryShown {
  readonly view: PlotView["kind"];
  /** The range shown (s since the epoch); null on the ring. */
  readonly range: TimeRange | null;
  /** The events of the range drawn (markers). */
  readonly events: readonly HistoryEvent[];
  readonly error: string | null;
}

/** A moving window from the recording is fetched again this often: a bucket's width, in bounds. */
export const MOVING_REFRESH_MIN_MS = 2000;
export const MOVING_REFRESH_MAX_MS = 60_000;

// The trace colours are plot definitions (lib/plots.ts); re-exported for the views.
export { TRACE_COLOURS, traceColour } from "./plots";

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
  /** The keyboard's focus is on the plotting area (interactive, as with the pointer on it). */
  private focusInside = false;
  /** An x range (shifted, as drawn) a step asks the next ring rebuild to show. */
  private stepZoom: readonly number[] | null = null;
  /** The newest frame's time when the ring view was last rebuilt (a paused picture ends there). */
  private ringDrawnTo_ms: number | null = null;
  private visible: boolean[];
  private tzShift_ms = 0;
  private revision = 0;
  private zoomed = false;
  /** Told when the plot is zoomed away from the moving window, or back on it. */
  onZoomedChange: ((zoomed: boolean) => void) | null = null;
  /** Told when the view changes and whenever a range of the recording is drawn or fails. */
  onHistory: ((shown: HistoryShown) => void) | null = null;
  private view: PlotView = { kind: "ring" };
  private readonly loader: RangeLoader | null;
  private readonly timer: Timer;
  private readonly clock: () => number;
  /** The newest answer of the recording (kept while a new range loads, to draw something). */
  private historyData: RangeData | null = null;
  private historyError: string | null = null;
  private refreshHandle: unknown = null;
  /** The range of the last history drawing (ms since the epoch). */
  private drawnRange_ms: { readonly from: number; readonly to: number } | null = null;
  /** The answer of the last history drawing. */
  private drawnData: RangeData | null = null;
  /** Per-axis `uirevision`s of history drawings (the layout's keeps the drag mode). */
  private xRevision = 0;
  private yRevision = 0;
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
    const history = options.history;
    this.timer = history?.timer ?? browserTimer;
    this.clock = history?.now_ms ?? Date.now;
    this.loader =
      history === undefined || options.readOnly
        ? null
        : new RangeLoader(
            history.fetchRange,
            (data) => this.received(data),
            (reason) => this.failed(reason),
            history.debounce_ms,
            this.timer,
          );
    this.view = this.viewForWindow(this.window_ms);
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

  /** Whether the plot can show the recording (the panel's plots; not the kiosk's). */
  get reachesHistory(): boolean {
    return this.loader !== null;
  }

  get viewKind(): PlotView["kind"] {
    return this.view.kind;
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
    const axes = this.backend.zoomedAxes(this.el);
    if (this.loader !== null) this.followPerson(axes.xaxis);
    if (this.el === null) return;
    const keys = Object.keys(axes);
    // A history view sets its x range itself: only the person's y zoom counts there.
    const zoomed =
      this.view.kind === "fixed" ||
      (this.view.kind === "ring" ? keys.length > 0 : keys.some((k) => k !== "xaxis"));
    this.setZoomed(zoomed);
  }

  /**
   * A person zoomed or panned to `x` (Plotly's x range, or undefined after an autoscale). On
   * the ring, a view inside what the plot holds stays a zoom of the moving window (no fetch);
   * one reaching before it goes into the recording. A history view follows every move with a
   * debounced fetch of the new range; an autoscale there is "Back to live".
   */
  private followPerson(x: readonly unknown[] | undefined): void {
    if (x === undefined) {
      if (this.view.kind === "fixed") this.backToLive();
      return;
    }
    const from_ms = axisTimeToEpochS(x[0], this.tzShift_ms) * 1000;
    const to_ms = axisTimeToEpochS(x[1], this.tzShift_ms) * 1000;
    if (!Number.isFinite(from_ms) || !Number.isFinite(to_ms) || !(to_ms > from_ms)) return;
    const tolerance_ms = (to_ms - from_ms) / 1000;
    if (this.view.kind !== "ring") {
      const drawn = this.drawnRange_ms;
      // Our own drawing of a range is no move of the person's.
      if (drawn !== null && Math.abs(drawn.from - from_ms) <= tolerance_ms && Math.abs(drawn.to - to_ms) <= tolerance_ms) return;
    }
    // Plotly shows the person's range already: nothing to draw before its answer.
    this.goTo({ from: from_ms, to: to_ms }, false);
  }

  /**
   * The one decision for a new time range, a person's (Plotly shows it already) or a step's
   * (`draw`: put Plotly on it here). A history view follows with a debounced fetch; on the ring,
   * a range inside what the plot holds stays a zoom of the moving window (no fetch), one reaching
   * before it goes into the recording. Without a recording (the loader) only the ring zoom.
   */
  private goTo(range: SpanMs, draw: boolean): void {
    const { from, to } = range;
    if (this.loader !== null) {
      const held = this.ringHeldFrom_ms();
      if (this.view.kind !== "ring" || held === null || from < held - (to - from) / 100) {
        this.enterView({ kind: "fixed", from_ms: from, to_ms: to }, { immediate: false, redraw: draw, fresh: false });
        return;
      }
    }
    if (draw) this.zoomRing(range);
  }

  /** Show `range` as a zoom of the ring view (a step's, as a person's Plotly zoom would). */
  private zoomRing(range: SpanMs): void {
    const el = this.el;
    if (el === null) return;
    const x = [range.from - this.tzShift_ms, range.to - this.tzShift_ms];
    if (this.paused) {
      // Paused: the frozen picture stays (Plotly's relayout, as a person's zoom; no data added).
      this.backend.relayout(el, { "xaxis.autorange": false, "xaxis.range": x });
    } else {
      this.stepZoom = x;
      this.rebuild(el);
    }
    this.setZoomed(true);
  }

  /**
   * A step of the time axis from a button or a key (lib/plotSteps.ts): zoom in or out around
   * the centre, pan earlier or later by half the range in view. The new range takes the same
   * decision as a person's zoom or pan (`goTo`); "Later" onto now is back to live. A plot
   * without the recording stays within what its ring view holds.
   */
  step(step: PlotStep): void {
    if (this.el === null || this.options.readOnly) return;
    const shown = this.shownRange_ms();
    if (shown === null) return;
    // Without the recording, nothing is newer than the ring's newest frame.
    const now = this.loader === null ? (this.ring.newestTime() ?? this.now_ms()) : this.now_ms();
    let next = stepRange(shown, step, now);
    if (next !== null && next !== "live" && this.loader === null) next = this.withinRing(next, now);
    if (next === null) return;
    if (next !== "live") this.goTo(next, true);
    // Already live: nothing to redraw.
    else if (this.paused || this.zoomed || this.view.kind === "fixed") this.backToLive();
  }

  /** The range in view (ms since the epoch): a fixed view's own (even before it is drawn). */
  private shownRange_ms(): SpanMs | null {
    if (this.view.kind === "fixed") return { from: this.view.from_ms, to: this.view.to_ms };
    const r = this.visibleRange();
    return r === null ? null : { from: r.from_s * 1000, to: r.to_s * 1000 };
  }

  /** `range` moved to start no earlier than the ring view holds; "live" once it covers it all. */
  private withinRing(range: SpanMs, now_ms: number): SpanMs | "live" | null {
    const held = this.ringHeldFrom_ms();
    if (held === null) return null;
    if (range.from >= held) return range;
    const to = Math.min(now_ms, held + (range.to - range.from));
    return to >= now_ms ? "live" : { from: held, to };
  }

  /** The oldest time the ring view draws: its window back from the newest frame, or the ring's oldest. */
  private ringHeldFrom_ms(): number | null {
    const newest = this.ring.newestTime();
    if (newest === null) return null;
    return Math.max(newest - this.window_ms, this.ring.timeAt(this.ring.oldestSeq));
  }

  private viewForWindow(window_ms: number): PlotView {
    return this.loader !== null && window_ms > RING_WINDOW_MAX_MS ? { kind: "moving", span_ms: window_ms } : { kind: "ring" };
  }

  /**
   * Show a fixed range of the past (a marker's jump, a custom range), fetched at once; the
   * plot leaves a pause (it shows what was asked for).
   */
  showRange(range: TimeRange): void {
    if (this.loader === null || !(range.to_s > range.from_s)) return;
    this.paused = false;
    this.enterView({ kind: "fixed", from_ms: range.from_s * 1000, to_ms: range.to_s * 1000 }, { immediate: true, redraw: true, fresh: true });
  }

  /** Whether the plot shows `range` (a fixed range of the past, to the millisecond). */
  isShowing(range: TimeRange): boolean {
    const view = this.view;
    return (
      view.kind === "fixed" && Math.abs(view.from_ms - range.from_s * 1000) < 1 && Math.abs(view.to_ms - range.to_s * 1000) < 1
    );
  }

  /**
   * Switch views. `immediate`: fetch now, not after the debounce; `redraw`: draw the new range at
   * once (with what is at hand) rather than when its answer comes (a person's move has put
   * Plotly on the range already); `fresh`: a new `uirevision`, dropping the person's zoom.
   */
  private enterView(view: PlotView, how: { immediate: boolean; redraw: boolean; fresh: boolean }): void {
    this.clearRefresh();
    this.view = view;
    if (how.fresh) this.revision++;
    if (view.kind === "ring") {
      this.loader?.stop();
      this.drawnData = null;
      this.historyData = null;
      this.historyError = null;
      this.drawnRange_ms = null;
      this.needsRebuild = true;
    } else {
      this.requestRange(how.immediate);
      if (how.redraw) this.needsRebuild = true;
    }
    this.setZoomed(view.kind === "fixed");
    this.mark();
    this.tell();
  }

  /** The range the view asks for now (ms since the epoch). */
  private wantedRange_ms(): { from: number; to: number } {
    const view = this.view;
    if (view.kind === "fixed") return { from: view.from_ms, to: view.to_ms };
    const to = this.now_ms();
    return { from: to - (view.kind === "moving" ? view.span_ms : this.window_ms), to };
  }

  /** Now on the frames' time axis: the newest frame while frames come, else the clock. */
  private now_ms(): number {
    const newest = this.ring.newestTime();
    const clock = this.clock();
    // The receive times are the service's clock; the browser's may differ by a little.
    return newest !== null && Math.abs(clock - newest) < 30_000 ? newest : clock;
  }

  private pointsWanted(): number {
    const margin = plotMargin(this.spec.series.some((s) => s.axis === "y2"));
    const width = (this.el as (HTMLElement & { clientWidth?: number }) | null)?.clientWidth;
    return bucketsForWidth((width ?? Number.NaN) - margin.l - margin.r);
  }

  private requestRange(immediate: boolean): void {
    if (this.loader === null || this.view.kind === "ring") return;
    const { from, to } = this.wantedRange_ms();
    this.loader.request({ from_s: from / 1000, to_s: to / 1000 }, this.pointsWanted(), immediate);
  }

  private received(data: RangeData): void {
    if (this.view.kind === "ring") return;
    this.historyData = data;
    this.historyError = null;
    this.needsRebuild = true;
    if (this.view.kind === "moving") this.scheduleRefresh();
  }

  private failed(reason: string): void {
    if (this.view.kind === "ring") return;
    this.historyError = reason;
    this.tell();
    if (this.view.kind === "moving") this.scheduleRefresh();
  }

  /** A moving window from the recording asks again when about a new bucket has filled. */
  private scheduleRefresh(): void {
    this.clearRefresh();
    if (this.view.kind !== "moving") return;
    const every_ms = Math.min(MOVING_REFRESH_MAX_MS, Math.max(MOVING_REFRESH_MIN_MS, this.view.span_ms / this.pointsWanted()));
    this.refreshHandle = this.timer.set(() => {
      this.refreshHandle = null;
      // Paused: frozen until resumed (which goes back to live and asks again). Out of view: no
      // request, only the next turn (the plot asks again within a turn of coming into view).
      if (this.view.kind !== "moving" || this.paused) return;
      if (this.onScreen) this.requestRange(true);
      else this.scheduleRefresh();
    }, every_ms);
  }

  private clearRefresh(): void {
    if (this.refreshHandle !== null) this.timer.clear(this.refreshHandle);
    this.refreshHandle = null;
  }

  /** The range in view now (s since the epoch): what an export of "the view" covers. */
  visibleRange(): TimeRange | null {
    if (this.view.kind !== "ring") {
      const r = this.drawnRange_ms ?? this.wantedRange_ms();
      return { from_s: r.from / 1000, to_s: r.to / 1000 };
    }
    const x = this.el !== null ? this.backend.zoomedAxes(this.el).xaxis : undefined;
    if (x !== undefined) {
      const from_s = axisTimeToEpochS(x[0], this.tzShift_ms);
      const to_s = axisTimeToEpochS(x[1], this.tzShift_ms);
      if (Number.isFinite(from_s) && Number.isFinite(to_s) && to_s > from_s) return { from_s, to_s };
    }
    // Paused, the picture ends at the newest frame when it froze, not the ring's newest.
    const to = (this.paused ? this.ringDrawnTo_ms : null) ?? this.ring.newestTime() ?? this.clock();
    return { from_s: (to - this.window_ms) / 1000, to_s: to / 1000 };
  }

  private tell(): void {
    if (this.onHistory === null) return;
    // A range of the past is told as soon as it is chosen (its markers with it); a moving window
    // as last drawn.
    const view = this.view.kind;
    const r = view === "ring" ? null : view === "fixed" ? this.wantedRange_ms() : (this.drawnRange_ms ?? this.wantedRange_ms());
    this.onHistory({
      view: this.view.kind,
      range: r === null ? null : { from_s: r.from / 1000, to_s: r.to / 1000 },
      events: this.view.kind === "ring" ? [] : (this.historyData?.events ?? []),
      error: this.historyError,
    });
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
    // The picked window again: from the ring, or a long one from the recording (asked at once).
    this.enterView(this.viewForWindow(this.window_ms), { immediate: true, redraw: true, fresh: true });
    this.setZoomed(false);
    if (this.el !== null) this.rebuild(this.el);
    this.mark();
  }

  /** Save the plot as drawn now as `filename`.png. */
  exportPng(filename: string): void {
    if (this.el !== null) this.backend.downloadPng?.(this.el, filename);
  }

  unmount(): void {
    this.loader?.stop();
    this.clearRefresh();
    if (this.el !== null) this.backend.purge(this.el);
    this.el = null;
  }

  /** A window picked: on the ring up to 2 min, longer ones from the recording (moving with now). */
  setWindow(window_ms: number): void {
    if (window_ms === this.window_ms && this.view.kind !== "fixed") return;
    this.window_ms = window_ms;
    // A new window length starts from autorange, not the old zoom (a new revision).
    this.enterView(this.viewForWindow(window_ms), { immediate: true, redraw: true, fresh: true });
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
    this.interactiveChanged(before);
  }

  /** The keyboard's focus entered or left the plotting area: interactive as with the pointer. */
  setFocusInside(inside: boolean): void {
    if (inside === this.focusInside) return;
    const before = this.interactive;
    this.focusInside = inside;
    this.interactiveChanged(before);
  }

  private interactiveChanged(before: boolean): void {
    // At once, not at the next tick: the person may start dragging a zoom box right away.
    if (this.interactive !== before && !this.paused && this.el !== null) this.rebuild(this.el);
  }

  /** Interactive (zoom, pan, mode bar; hover too when paused), or a static picture. */
  get interactive(): boolean {
    // A view of the recording changes only when an answer comes: always interactive.
    return !this.options.readOnly && (this.paused || this.pointerInside || this.focusInside || this.view.kind !== "ring");
  }

  setTraceVisible(index: number, visible: boolean): void {
    if (this.visible[index] === undefined || this.visible[index] === visible) return;
    this.visible[index] = visible;
    // A history drawing has several traces per signal (min, max, the ring's newest): redraw.
    if (this.view.kind !== "ring") this.needsRebuild = true;
    else if (this.el !== null) this.backend.restyle(this.el, { visible }, [index]);
  }

  isTraceVisible(index: number): boolean {
    return this.visible[index] ?? false;
  }

  /** Whether an update would do anything now. */
  hasWork(): boolean {
    if (this.el === null) return false;
    // A history view: only when an answer came (or a redraw was asked for), never per frame.
    if (this.view.kind !== "ring") return this.needsRebuild;
    if (this.paused) return false;
    return this.needsRebuild || this.readSeq !== this.ring.endSeq;
  }

  /** Append what arrived since the last update (or rebuild); true if Plotly was called. */
  update(now_ms: number): boolean {
    const el = this.el;
    if (el === null) return false;
    if (this.view.kind !== "ring") {
      if (!this.needsRebuild) return false;
      this.drawHistory(el);
      this.lastUpdate_ms = now_ms;
      return true;
    }
    if (this.paused) return false;
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
    const xs = chunk.xs[0] ?? [];
    const axes = this.liveTicks ? { xaxis: this.ticksBefore(xs[xs.length - 1] ?? Number.NaN) } : undefined;
    this.backend.extendTraces(el, { x: chunk.xs, y: chunk.ys }, indices, this.maxPoints, axes);
    this.points = Math.min(this.maxPoints, this.points + chunk.buckets * POINTS_PER_BUCKET);
    this.lastUpdate_ms = now_ms;
    this.updates++;
    this.mark();
    return true;
  }

  private rebuild(el: HTMLElement): void {
    if (this.view.kind !== "ring") {
      this.drawHistory(el);
      return;
    }
    this.needsRebuild = false;
    this.tzShift_ms = new Date().getTimezoneOffset() * 60_000;
    this.bucketer = this.newBucketer();
    const newest = this.ring.newestTime();
    this.ringDrawnTo_ms = newest;
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
    const kept = this.drawnRevision === this.revision ? this.backend.zoomedAxes(el) : {};
    // A step's x range (zoomRing), with the person's y zoom kept.
    const zoom = this.stepZoom !== null ? { ...kept, xaxis: this.stepZoom } : kept;
    this.stepZoom = null;
    this.drawnRevision = this.revision;
    this.backend.react(el, data, this.layout(zoom), this.config());
    this.updates++;
    this.mark();
  }

  /**
   * Draw the view's range from the recording: the newest answer as min/max envelopes, and what
   * the ring holds after the answer's newest frame (not yet recorded, or no recording at all)
   * as a line per signal; the events of the range as dotted lines on the time axis.
   */
  private drawHistory(el: HTMLElement): void {
    this.needsRebuild = false;
    this.tzShift_ms = new Date().getTimezoneOffset() * 60_000;
    const shift = this.tzShift_ms;
    const { from, to } = this.wantedRange_ms();
    const data = this.historyData;
    const sets = data !== null ? envelopeTraceSets(data.answer, this.spec, shift) : this.traces.map(() => []);
    const recorded_s = data !== null ? newestRecorded(data.answer) : null;
    const tailFrom = Math.max(from, recorded_s === null ? -Infinity : recorded_s * 1000 + 1e-3);
    const points = this.pointsWanted();
    const tail = new MinMaxBucketer(this.ringChannels, Math.max((to - from) / points, 1), points, (t) => t - shift);
    tail.feedRing(this.ring, this.ring.firstSeqAtOrAfter(tailFrom), this.ring.firstSeqAtOrAfter(to));
    const chunk = tail.take();
    const traces: object[] = [];
    let drawnPoints = 0;
    this.traces.forEach((trace, i) => {
      const visible = this.visible[i] ?? true;
      const own = sets[i] ?? [];
      for (const t of own) traces.push({ ...t, visible });
      const tailX = chunk?.xs[i] ?? [];
      traces.push({ ...this.traceStyle(trace, i), x: tailX, y: chunk?.ys[i] ?? [], showlegend: false });
      if (i === 0) drawnPoints = ((own[0] as { x?: unknown[] } | undefined)?.x?.length ?? 0) + tailX.length;
    });
    const range_s = { from_s: from / 1000, to_s: to / 1000 };
    const shapes = markersOf(data?.events ?? [], range_s).map((m) => ({
      type: "line",
      xref: "x",
      yref: "paper",
      x0: m.time_s * 1000 - shift,
      x1: m.time_s * 1000 - shift,
      y0: 0,
      y1: 1,
      line: { color: m.kind === "alarm" ? "#D55E00" : "#888", width: 1, dash: "dot" },
    }));
    // Plotly keeps a person's axis range within its `uirevision`: where it shows another range
    // than this one (a jump, a moving window's step), a new x revision makes it take this one. A
    // new range of the past also fits its y axes to its data again (Plotly's zoom-out button
    // widens y as well as x); a moving window's refresh keeps a person's y zoom. Per axis, so
    // the layout's revision keeps the person's drag mode (a pan goes on panning).
    const x = this.backend.zoomedAxes(el).xaxis;
    const shown_from = x !== undefined ? axisTimeToEpochS(x[0], shift) * 1000 : Number.NaN;
    const shown_to = x !== undefined ? axisTimeToEpochS(x[1], shift) * 1000 : Number.NaN;
    const tolerance_ms = (to - from) / 1000;
    if (!(Math.abs(shown_from - from) <= tolerance_ms && Math.abs(shown_to - to) <= tolerance_ms)) this.xRevision++;
    if (this.view.kind === "fixed" && data !== this.drawnData) this.yRevision++;
    this.drawnData = data;
    this.drawnRevision = this.revision;
    const layout: Record<string, unknown> = { ...(this.layout({ xaxis: [from - shift, to - shift] }) as Record<string, unknown>), shapes };
    const axisRevision = (axis: string, revision: string) => {
      const a = layout[axis];
      if (typeof a === "object" && a !== null) layout[axis] = { ...a, uirevision: revision };
    };
    axisRevision("xaxis", `x${this.xRevision}`);
    axisRevision("yaxis", `y${this.yRevision}`);
    axisRevision("yaxis2", `y${this.yRevision}`);
    this.drawnRange_ms = { from, to };
    this.points = drawnPoints;
    this.backend.react(el, traces, layout, this.config());
    this.updates++;
    el.dataset.from = String(range_s.from_s);
    el.dataset.to = String(range_s.to_s);
    el.dataset.frames = String(data?.answer.frames ?? 0);
    this.mark();
    this.tell();
  }

  private mark(): void {
    if (this.el === null) return;
    this.el.dataset.points = String(this.points);
    this.el.dataset.paused = this.paused ? "true" : "false";
    this.el.dataset.windowMs = String(this.window_ms);
    this.el.dataset.interactive = this.interactive ? "true" : "false";
    this.el.dataset.zoomed = this.zoomed ? "true" : "false";
    this.el.dataset.view = this.view.kind;
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
      // 1 px on the panel: the browser strokes a line of at most 1 px as a hairline, which it
      // rasterises at about a quarter of the cost of a 1.5 px stroke (bench/ui: raster CPU per
      // redraw). The kiosk, read from three metres, keeps the heavier line.
      line: { width: this.options.readOnly ? 1.5 : 1, color: traceColour(i), dash: trace.axis === "y2" ? "dot" : "solid" },
      connectgaps: false,
      // The value with the layout's unit ("J 1: 12.35 degree"), the time in the hover's header.
      ...(this.options.readOnly
        ? { hoverinfo: "skip" }
        : { hovertemplate: `${trace.name}: %{y:.4~r} ${trace.field.unit}<extra></extra>` }),
      hoverlabel: { namelength: -1 },
    };
  }

  /**
   * Whether the time axis is drawn with our own ticks (`timeTicks`) that each live update moves:
   * a live plot showing the ring as a static picture, not zoomed on its time axis.
   */
  private liveTicks = false;
  /** The plotting area's width (px) at the last drawing, for the number of time ticks. */
  private areaWidth_px = Number.NaN;

  /** Time ticks for the moving window ending at `newestX` (a numeric date, shifted). */
  private ticksBefore(newestX: number): TimeTicks {
    // A little over the window: the oldest points kept may reach a bucket further back.
    return this.ticksOver(newestX - this.window_ms * 1.05, newestX);
  }

  private ticksOver(from: number, to: number): TimeTicks {
    // Labels of larger text (the kiosk's) need more room each.
    const spacing_px = Math.max(TICK_SPACING_PX, 9 * (this.options.fontSize_px ?? 11));
    return timeTicks(from, to, this.areaWidth_px, spacing_px);
  }

  /**
   * The time axis. A live plot nobody points at draws it as a linear axis with our own ticks: a
   * date axis reads each sample's time through Plotly's date parser and works out date ticks on
   * every redraw (lib/timeTicks.ts). An interactive plot or a view of the recording keeps the
   * date axis, for its hover and for zooming into dates.
   */
  private timeAxis(zoom: Readonly<Record<string, readonly unknown[]>>, grid: string): { axis: object; range: number[] | null } {
    const common = { autorange: true, gridcolor: grid, ticklabeloverflow: "allow" };
    if (this.view.kind !== "ring" || this.interactive) {
      this.liveTicks = false;
      return { axis: { ...common, type: "date" }, range: null };
    }
    const width = (this.el as (HTMLElement & { clientWidth?: number }) | null)?.clientWidth;
    const margin = plotMargin(this.spec.series.some((s) => s.axis === "y2"));
    if (width !== undefined && width > 0) this.areaWidth_px = width - margin.l - margin.r;
    // A zoom carried over from the date axis: its range may be Plotly's date text.
    const zoomed = zoom.xaxis?.map((v) => (typeof v === "number" ? v : axisTimeToEpochS(v, 0) * 1000)) ?? null;
    this.liveTicks = zoomed === null;
    const newest = this.ring.newestTime();
    const ticks =
      zoomed !== null
        ? this.ticksOver(zoomed[0] ?? Number.NaN, zoomed[1] ?? Number.NaN)
        : this.ticksBefore(newest === null ? Number.NaN : newest - this.tzShift_ms);
    return { axis: { ...common, type: "linear", tickmode: "array", ...ticks }, range: zoomed };
  }

  private layout(zoom: Readonly<Record<string, readonly unknown[]>> = {}): object {
    const dark = this.options.theme === "dark";
    const fg = dark ? "#d8dde3" : "#222";
    const grid = dark ? "#2f3740" : "#e3e3e3";
    const twoAxes = this.spec.series.some((s) => s.axis === "y2");
    const time = this.timeAxis(zoom, grid);
    if (time.range !== null) zoom = { ...zoom, xaxis: time.range };
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
      xaxis: time.axis,
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
