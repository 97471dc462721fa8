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
 *
 * This module is `LivePlot`'s state: the view (ring, moving, fixed) and the moves between views
 * (a person's zoom or pan, a step, a jump, back to live), pause, visibility, interactivity, and
 * `update()` for the coordinator. How a plot looks (trace style, time axis, layout, config) is
 * lib/plotAppearance.ts; each view's own side is a module of its own: the ring's reading
 * (lib/plotRingView.ts), the moving window's policy (lib/plotMovingView.ts), a fixed range's
 * decisions (lib/plotFixedView.ts), and the recording's fetching and traces
 * (lib/plotRecordingView.ts). Must not import Plotly (only through `PlotBackend`) or React.
 */
import { POINTS_PER_BUCKET } from "./decimate";
import { markersOf, type RangeData, type TimeRange } from "./historyView";
import {
  BUCKETS_PER_WINDOW,
  emptyTraces,
  historyLayout,
  markerShapes,
  plotAreaWidth_px,
  plotConfig,
  plotLayout,
  ticksBefore,
  timeAxis,
  traceStyle,
  type AxisRanges,
  type PlotLook,
} from "./plotAppearance";
import {
  PlotRecording,
  historyTraces,
  nowOnFrames,
  pointsWanted,
  rangeWanted,
  type DrawnPlot,
  type HistoryShown,
  type PlotHistorySource,
  type PlotView,
} from "./plotRecordingView";
import { axisSpan_ms, reachesRecording, RecordingRevisions, sameSpan, showsRange } from "./plotFixedView";
import { refreshAction, viewForWindow } from "./plotMovingView";
import { RingView } from "./plotRingView";
import { tracesOf, type ChannelMap, type PlotSpec, type TraceInfo } from "./plots";
import { stepRange, type PlotStep, type SpanMs } from "./plotSteps";
import type { PlotBackend } from "./plotBackend";
import type { SampleRing } from "./ringBuffer";

export type { PlotBackend } from "./plotBackend";

export interface LivePlotOptions extends PlotLook {
  readonly window_ms: number;
  /** The plot's way into the recording (the panel's plots); none: the ring only (the kiosk). */
  readonly history?: PlotHistorySource;
}

export class LivePlot {
  readonly spec: PlotSpec;
  readonly traces: readonly TraceInfo[];
  /** 0 … traces − 1, made once: every live redraw names all its traces to Plotly. */
  private readonly traceIndices: number[];
  private readonly ring: SampleRing;
  private readonly ringChannels: number[];
  private readonly backend: PlotBackend;
  private readonly options: LivePlotOptions;
  private el: HTMLElement | null = null;
  private window_ms: number;
  /** The ring view's reading of the ring (its buckets, what it holds). */
  private readonly ringView: RingView;
  private needsRebuild = true;
  private paused = false;
  private pointerInside = false;
  /** The keyboard's focus is on the plotting area (interactive, as with the pointer on it). */
  private focusInside = false;
  /** An x range (shifted, as drawn) a step asks the next ring rebuild to show. */
  private stepZoom: readonly number[] | null = null;
  private readonly visible: boolean[];
  private tzShift_ms = 0;
  /**
   * Whether the time axis is drawn with our own ticks (`ticksBefore`) that each live update moves:
   * a live plot showing the ring as a static picture, not zoomed on its time axis.
   */
  private liveTicks = false;
  /** The plotting area's width (px) at the last drawing, for the number of time ticks. */
  private areaWidth_px = Number.NaN;

  private revision = 0;
  private zoomed = false;
  /** Told when the plot is zoomed away from the moving window, or back on it. */
  onZoomedChange: ((zoomed: boolean) => void) | null = null;
  /** Told when the view changes and whenever a range of the recording is drawn or fails. */
  onHistory: ((shown: HistoryShown) => void) | null = null;
  private view: PlotView = { kind: "ring" };
  /** The plot's requests to the recording; null: the ring only (the kiosk). */
  private readonly recording: PlotRecording | null;
  private readonly clock: () => number;
  /** What a drawing of the recording draws from (made once). */
  private readonly drawnPlot: DrawnPlot;
  /** The newest answer of the recording (kept while a new range loads, to draw something). */
  private historyData: RangeData | null = null;
  private historyError: string | null = null;
  /** The range of the last history drawing (ms since the epoch). */
  private drawnRange_ms: SpanMs | null = null;
  /** Per-axis `uirevision`s of history drawings (the layout's keeps the drag mode). */
  private readonly revisions = new RecordingRevisions();
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
    this.traceIndices = this.traces.map((_, i) => i);
    this.ring = ring;
    this.ringChannels = this.traces.map((t) => channels.channelOf(t.fieldName, t.channel));
    this.backend = backend;
    this.options = options;
    this.window_ms = options.window_ms;
    this.visible = this.traces.map(() => true);
    this.ringView = new RingView(ring, this.ringChannels, this.window_ms);
    const history = options.history;
    this.clock = history?.now_ms ?? Date.now;
    this.recording =
      history === undefined || options.readOnly
        ? null
        : new PlotRecording(history, {
            answered: (data) => this.received(data),
            failed: (reason) => this.failed(reason),
            refreshDue: () => this.refreshDue(),
          });
    this.drawnPlot = {
      spec,
      traces: this.traces,
      visible: this.visible,
      readOnly: options.readOnly,
      ring,
      ringChannels: this.ringChannels,
    };
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
    return this.recording !== null;
  }

  get viewKind(): PlotView["kind"] {
    return this.view.kind;
  }

  /** Create the Plotly plot in `el` (once). */
  mount(el: HTMLElement): void {
    this.el = el;
    this.backend.newPlot(el, emptyTraces(this.traces, this.visible, this.options.readOnly), this.layout(), plotConfig(this.interactive));
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
    if (this.recording !== null) this.followPerson(axes.xaxis);
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
    const range = axisSpan_ms(x, this.tzShift_ms);
    if (range === null) return;
    // Our own drawing of a range is no move of the person's.
    if (this.view.kind !== "ring" && sameSpan(range, this.drawnRange_ms)) return;
    // Plotly shows the person's range already: nothing to draw before its answer.
    this.goTo(range, false);
  }

  /**
   * The one decision for a new time range, a person's (Plotly shows it already) or a step's
   * (`draw`: put Plotly on it here). A history view follows with a debounced fetch; on the ring,
   * a range inside what the plot holds stays a zoom of the moving window (no fetch), one reaching
   * before it goes into the recording. Without a recording (the loader) only the ring zoom.
   */
  private goTo(range: SpanMs, draw: boolean): void {
    if (this.recording !== null && reachesRecording(this.view.kind, this.ringView.heldFrom_ms(), range)) {
      this.enterView({ kind: "fixed", from_ms: range.from, to_ms: range.to }, { immediate: false, redraw: draw, fresh: false });
      return;
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
    const now = this.recording === null ? (this.ring.newestTime() ?? this.now_ms()) : this.now_ms();
    let next = stepRange(shown, step, now);
    if (next !== null && next !== "live" && this.recording === null) next = this.ringView.within(next, now);
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

  private viewForWindow(window_ms: number): PlotView {
    return viewForWindow(this.recording !== null, window_ms);
  }

  /**
   * Show a fixed range of the past (a marker's jump, a custom range), fetched at once; the
   * plot leaves a pause (it shows what was asked for).
   */
  showRange(range: TimeRange): void {
    if (this.recording === null || !(range.to_s > range.from_s)) return;
    this.paused = false;
    this.enterView({ kind: "fixed", from_ms: range.from_s * 1000, to_ms: range.to_s * 1000 }, { immediate: true, redraw: true, fresh: true });
  }

  /** Whether the plot shows `range` (a fixed range of the past, to the millisecond). */
  isShowing(range: TimeRange): boolean {
    return showsRange(this.view, range);
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
      this.recording?.stopRequests();
      this.revisions.reset();
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
  private wantedRange_ms(): SpanMs {
    return rangeWanted(this.view, this.now_ms(), this.window_ms);
  }

  /** Now on the frames' time axis: the newest frame while frames come, else the clock. */
  private now_ms(): number {
    return nowOnFrames(this.ring.newestTime(), this.clock());
  }

  /** The element's width (px), when it has one (the tests' fake elements may not). */
  private elementWidth_px(): number | undefined {
    return (this.el as (HTMLElement & { clientWidth?: number }) | null)?.clientWidth;
  }

  private pointsWanted(): number {
    return pointsWanted(this.spec, this.elementWidth_px());
  }

  private requestRange(immediate: boolean): void {
    if (this.recording === null || this.view.kind === "ring") return;
    this.recording.request(this.wantedRange_ms(), this.pointsWanted(), immediate);
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
    this.recording?.scheduleRefresh(this.view.span_ms, this.pointsWanted());
  }

  private refreshDue(): void {
    const action = refreshAction(this.view.kind, this.paused, this.onScreen);
    if (action === "ask") this.requestRange(true);
    else if (action === "later") this.scheduleRefresh();
  }

  private clearRefresh(): void {
    this.recording?.clearRefresh();
  }

  /** The range in view now (s since the epoch): what an export of "the view" covers. */
  visibleRange(): TimeRange | null {
    if (this.view.kind !== "ring") {
      const r = this.drawnRange_ms ?? this.wantedRange_ms();
      return { from_s: r.from / 1000, to_s: r.to / 1000 };
    }
    const zoom = axisSpan_ms(this.el !== null ? this.backend.zoomedAxes(this.el).xaxis : undefined, this.tzShift_ms);
    if (zoom !== null) return { from_s: zoom.from / 1000, to_s: zoom.to / 1000 };
    // Paused: the range of the picture as it froze, not up to the ring's newest.
    const frozen = this.paused ? this.ringView.drawnRange() : null;
    if (frozen !== null) return { from_s: frozen.from / 1000, to_s: frozen.to / 1000 };
    const to = this.ring.newestTime() ?? this.clock();
    return { from_s: this.ringView.start_ms(to) / 1000, to_s: to / 1000 };
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
    this.recording?.stopRequests();
    this.clearRefresh();
    if (this.el !== null) this.backend.purge(this.el);
    this.el = null;
  }

  /** A window picked: on the ring up to 2 min, longer ones from the recording (moving with now). */
  setWindow(window_ms: number): void {
    if (window_ms === this.window_ms && this.view.kind !== "fixed") return;
    this.window_ms = window_ms;
    this.ringView.setWindow(window_ms);
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
    return this.needsRebuild || this.ringView.hasNew();
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
    if (this.needsRebuild || this.ringView.fellBehind()) {
      this.rebuild(el);
      this.lastUpdate_ms = now_ms;
      return true;
    }
    const chunk = this.ringView.takeNew();
    if (chunk === null) return false;
    const xs = chunk.xs[0] ?? [];
    const axes = this.liveTicks
      ? { xaxis: ticksBefore(xs[xs.length - 1] ?? Number.NaN, this.window_ms, this.areaWidth_px, this.options.fontSize_px) }
      : undefined;
    this.backend.extendTraces(el, { x: chunk.xs, y: chunk.ys }, this.traceIndices, this.maxPoints, axes);
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
    this.ringView.shift_ms = this.tzShift_ms;
    const chunk = this.ringView.rebuild();
    const data = this.traces.map((trace, i) => ({
      ...traceStyle(trace, i, this.visible[i] ?? true, this.options.readOnly),
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
    this.backend.react(el, data, this.layout(zoom), plotConfig(this.interactive));
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
    const range = this.wantedRange_ms();
    const { from, to } = range;
    const data = this.historyData;
    const drawing = historyTraces(this.drawnPlot, data, range, this.pointsWanted(), shift);
    const range_s = { from_s: from / 1000, to_s: to / 1000 };
    const shapes = markerShapes(markersOf(data?.events ?? [], range_s), shift);
    // A new x revision where Plotly shows another range, a new y one for a new range of the past.
    this.revisions.next(this.view.kind, range, axisSpan_ms(this.backend.zoomedAxes(el).xaxis, shift), data);
    this.drawnRevision = this.revision;
    const layout = historyLayout(this.layout({ xaxis: [from - shift, to - shift] }), shapes, this.revisions.x, this.revisions.y);
    this.drawnRange_ms = { from, to };
    this.points = drawing.points;
    this.backend.react(el, drawing.traces, layout, plotConfig(this.interactive));
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

  /** Plotly's layout now, with `zoom`'s axis ranges (lib/plotAppearance.ts). */
  private layout(zoom: AxisRanges = {}): Record<string, unknown> {
    const interactive = this.interactive;
    const ringStatic = this.view.kind === "ring" && !interactive;
    let newestX = Number.NaN;
    if (ringStatic) {
      const width = this.elementWidth_px();
      if (width !== undefined && width > 0) this.areaWidth_px = plotAreaWidth_px(this.spec, width);
      const newest = this.ring.newestTime();
      if (newest !== null) newestX = newest - this.tzShift_ms;
    }
    const time = timeAxis(this.options, ringStatic, zoom, newestX, this.window_ms, this.areaWidth_px);
    this.liveTicks = time.ownTicks;
    return plotLayout(this.spec, this.options, this.revision, interactive, time, zoom);
  }
}
