/**
 * Layer: a live plot's drawing side, independent of React (plain TypeScript).
 *
 * The state `LivePlot` (lib/plots/plotting.ts) moves between views, and everything that draws it: the
 * coordinator's per-frame `update()` (the ring view's new buckets appended, a rebuild, or a
 * recording's answer drawn), the static picture or Plotly, the recording's requests and
 * refreshes, and the element's data attributes. `LivePlot` extends it with the moves (a
 * person's zoom, pan, steps and wheel, the panel's time axis, pause, back to live).
 * Must not import Plotly or React.
 */
import { axisShift_ms } from "../common/dates";
import { POINTS_PER_BUCKET } from "./decimate";
import { markersOf, type RangeData } from "./historyView";
import { RingBackfill } from "./plotBackfill";
import type { PlotBackend, StaticPicture } from "./plotBackend";
import { PlotlyOnDemand } from "./plotlyOnDemand";
import {
  BUCKETS_PER_WINDOW,
  emptyTraces,
  historyLayout,
  markerShapes,
  pictureDrawing,
  plotAreaWidth_px,
  plotConfig,
  plotLayout,
  ticksBefore,
  timeAxis,
  traceStyle,
  type AxisRanges,
  type PlotLook,
} from "./plotAppearance";
import { axisSpan_ms, RecordingRevisions } from "./plotFixedView";
import { refreshAction, viewForWindow } from "./plotMovingView";
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
import { RingView } from "./plotRingView";
import { tracesOf, type ChannelMap, type PlotSpec, type TraceInfo } from "./plots";
import type { SpanMs } from "./plotSteps";
import { recordingValuesAt, ringValuesAt, type TraceValue } from "./plotValues";
import type { PlotMove } from "./timeRange";
import type { SampleRing } from "../stream/ringBuffer";

export interface LivePlotOptions extends PlotLook {
  readonly window_ms: number;
  /**
   * Draws the ring view while the plot is not interactive (plots/canvasPlot.ts: the panel's plots
   * and the kiosk's, which is only ever its picture); none: Plotly draws every view.
   */
  readonly staticPicture?: StaticPicture;
  /** The plot's way into the recording (the panel's plots); none: the ring only (the kiosk). */
  readonly history?: PlotHistorySource;
}

/** A live plot's state and drawing; `LivePlot` (lib/plots/plotting.ts) adds the moves. */
export abstract class LivePlotDrawing {
  readonly spec: PlotSpec;

  readonly traces: readonly TraceInfo[];

  /** 0 … traces − 1, made once: every live redraw names all its traces to Plotly. */
  protected readonly traceIndices: number[];

  protected readonly ring: SampleRing;

  protected readonly ringChannels: number[];

  protected readonly backend: PlotBackend;

  protected readonly options: LivePlotOptions;

  protected el: HTMLElement | null = null;

  protected window_ms: number;

  /** The ring view's reading of the ring (its buckets, what it holds). */
  protected readonly ringView: RingView;

  protected needsRebuild = true;

  protected paused = false;

  protected pointerInside = false;

  /** The keyboard's focus is on the plotting area (interactive, as with the pointer on it). */
  protected focusInside = false;

  /** An x range (shifted, as drawn) a step asks the next ring rebuild to show. */
  protected stepZoom: readonly number[] | null = null;

  protected readonly visible: boolean[];

  protected tzShift_ms = 0;

  /**
   * Whether the time axis is drawn with our own ticks (`ticksBefore`) that each live update moves:
   * a live plot showing the ring as a static picture, not zoomed on its time axis.
   */
  protected liveTicks = false;

  /** The plotting area's width (px) at the last drawing, for the number of time ticks. */
  protected areaWidth_px = Number.NaN;

  /** The static picture, when the plot has one (the panel's plots and the kiosk's). */
  protected readonly picture: StaticPicture | null;

  /** The ring view is drawn by the picture now (Plotly's plot hidden and not updated). */
  protected onPicture = false;

  /** The zoom in force while on the picture (Plotly's layout, not updated then, has no say). */
  protected pictureZoom: AxisRanges = {};

  /**
   * Plotly's plot is made in the element (`plotlyIn`): the first time the plot is drawn by
   * Plotly, never for one that is only ever a picture (the kiosk's; a panel plot nobody
   * pointed at).
   */
  protected plotlyMounted = false;

  /** Plotly, asked for the first time the plot needs it (lib/plots/plotlyAdapter.ts loads it then). */
  private readonly plotly: PlotlyOnDemand;

  protected revision = 0;

  protected zoomed = false;

  /** Told when the plot is zoomed away from the moving window, or back on it. */
  onZoomedChange: ((zoomed: boolean) => void) | null = null;
  /** The window picked changed (here, or followed from a linked plot): its picker shows it. */
  onWindowChange: ((window_ms: number) => void) | null = null;

  /** Told when the view changes and whenever a range of the recording is drawn or fails. */
  onHistory: ((shown: HistoryShown) => void) | null = null;

  /** Told of each move a person makes on this plot (not of moves it follows): the panel's time axis. */
  onMove: ((move: PlotMove) => void) | null = null;

  /** Told after each drawing (the cursor's readout follows the axis). */
  onDrawn: (() => void) | null = null;

  /** Applying a move of another plot (`follow`): not told on. */
  protected following = false;

  /** The ring view's start from the recording while the ring holds less than the window. */
  protected readonly backfill: RingBackfill | null;

  protected view: PlotView = { kind: "ring" };

  /** The plot's requests to the recording; null: the ring only (the kiosk). */
  protected readonly recording: PlotRecording | null;

  protected readonly clock: () => number;

  /** What a drawing of the recording draws from (made once). */
  protected readonly drawnPlot: DrawnPlot;

  /** The newest answer of the recording (kept while a new range loads, to draw something). */
  protected historyData: RangeData | null = null;

  protected historyError: string | null = null;

  /** The range of the last history drawing (ms since the epoch). */
  protected drawnRange_ms: SpanMs | null = null;

  /** Per-axis `uirevision`s of history drawings (the layout's keeps the drag mode). */
  protected readonly revisions = new RecordingRevisions();

  /** `revision` of the last drawing: a rebuild within the same revision keeps the zoom. */
  protected drawnRevision = -1;

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
    this.picture = options.staticPicture ?? null;
    this.plotly = new PlotlyOnDemand(backend, () => this.plotlyCame());

    const history = options.history;
    this.backfill =
      history === undefined || options.readOnly
        ? null
        : new RingBackfill(history, ring, () => {
            if (this.view.kind === "ring") this.needsRebuild = true;
            this.tell(); // what of the window is recorded: said on the plot
          });
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

  /** Whether a person zoomed or panned the plot away from its moving window. */
  get isZoomed(): boolean {
    return this.zoomed;
  }

  /**
   * The values of each trace at `time_ms` (the panel's cursor): the ring's nearest sample, else
   * the recording's bucket the plot drew (or filled its window from); null where none.
   */
  valuesAt(time_ms: number): (TraceValue | null)[] {
    const fromRing = ringValuesAt(this.ring, this.ringChannels, time_ms);
    if (fromRing !== null) return fromRing;
    const answer = this.view.kind !== "ring" ? this.historyData?.answer : this.backfill?.data;
    return (answer != null ? recordingValuesAt(answer, this.traces, time_ms) : null) ?? this.traces.map(() => null);
  }

  protected viewForWindow(window_ms: number): PlotView {
    return viewForWindow(this.recording !== null, window_ms);
  }

  /** The range the view asks for now (ms since the epoch). */
  protected wantedRange_ms(): SpanMs {
    return rangeWanted(this.view, this.now_ms(), this.window_ms);
  }

  /** Now on the frames' time axis: the newest frame while frames come, else the clock. */
  protected now_ms(): number {
    return nowOnFrames(this.ring.newestTime(), this.clock());
  }

  /** The element's width (px), when it has one (the tests' fake elements may not). */
  protected elementWidth_px(): number | undefined {
    return (this.el as (HTMLElement & { clientWidth?: number }) | null)?.clientWidth;
  }

  protected pointsWanted(): number {
    return pointsWanted(this.spec, this.elementWidth_px());
  }

  protected requestRange(immediate: boolean): void {
    if (this.recording === null || this.view.kind === "ring") return;
    this.recording.request(this.wantedRange_ms(), this.pointsWanted(), immediate);
  }

  protected received(data: RangeData): void {
    if (this.view.kind === "ring") return;
    this.historyData = data;
    this.historyError = null;
    this.needsRebuild = true;
    if (this.view.kind === "moving") this.scheduleRefresh();
  }

  protected failed(reason: string): void {
    if (this.view.kind === "ring") return;
    this.historyError = reason;
    this.tell();
    if (this.view.kind === "moving") this.scheduleRefresh();
  }

  /** A moving window from the recording asks again when about a new bucket has filled. */
  protected scheduleRefresh(): void {
    this.clearRefresh();
    if (this.view.kind !== "moving") return;
    this.recording?.scheduleRefresh(this.view.span_ms, this.pointsWanted());
  }

  protected refreshDue(): void {
    const action = refreshAction(this.view.kind, this.paused, this.onScreen);
    if (action === "ask") this.requestRange(true);
    else if (action === "later") this.scheduleRefresh();
  }

  protected clearRefresh(): void {
    this.recording?.clearRefresh();
  }

  protected tell(): void {
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

  protected setZoomed(zoomed: boolean): void {
    if (zoomed === this.zoomed) return;
    this.zoomed = zoomed;
    this.mark();
    this.onZoomedChange?.(zoomed);
  }

  /** Save the plot as drawn now as `filename`.png: its picture while shown, else Plotly's plot. */
  exportPng(filename: string): void {
    if (this.onPicture && this.picture?.savePng !== undefined) this.picture.savePng(filename);
    else if (this.el !== null && this.plotlyMounted) this.backend.downloadPng?.(this.el, filename);
  }

  unmount(): void {
    this.recording?.stopRequests();
    this.backfill?.stop();
    this.clearRefresh();
    if (this.el !== null && this.plotlyMounted) this.backend.purge(this.el);
    this.plotlyMounted = false;
    this.el = null;
  }

  /**
   * Interactive (zoom, pan, mode bar; hover too when paused), or a static picture. A plot with a
   * picture stays the picture until Plotly has come (asked for here, the first time it is wanted).
   */
  get interactive(): boolean {
    return this.wantsInteractive && (this.picture === null || this.plotlyReady());
  }

  /** A person points at the plot or its keys, paused it, or it shows the recording. */
  protected get wantsInteractive(): boolean {
    // A view of the recording changes only when an answer comes: always interactive.
    return !this.options.readOnly && (this.paused || this.pointerInside || this.focusInside || this.view.kind !== "ring");
  }

  /** Whether Plotly can draw now; if not, the plot keeps its picture until it comes. */
  protected plotlyReady(): boolean {
    return this.plotly.ready();
  }

  /** Plotly has come: a plot that wants it is drawn by it at once (a person may start a zoom box). */
  private plotlyCame(): void {
    const el = this.el;
    if (el === null || !(this.wantsInteractive || this.picture === null)) return;
    this.needsRebuild = true;
    if (this.view.kind !== "ring") return; // the recording's drawing, at the next update
    if (this.paused && this.stepZoom === null && this.pictureZoom.xaxis === undefined) {
      // Paused on the picture: Plotly shows the range that froze, not the ring's newest.
      const frozen = this.ringView.drawnRange();
      if (frozen !== null) this.stepZoom = [frozen.from - this.tzShift_ms, frozen.to - this.tzShift_ms];
    }
    this.rebuild(el);
  }

  /** Plotly's plot in `el`, made the first time the plot is drawn by Plotly. */
  protected plotlyIn(el: HTMLElement): PlotBackend {
    if (!this.plotlyMounted) {
      this.plotlyMounted = true;
      this.backend.newPlot(el, emptyTraces(this.traces, this.visible, this.options.readOnly), this.layout(), plotConfig(this.interactive));
      this.backend.onRelayout?.(el, () => this.personRelayout());
    }
    return this.backend;
  }

  /** After a person's zoom, pan or autoscale on Plotly's plot (`LivePlot` follows it). */
  protected abstract personRelayout(): void;

  setTraceVisible(index: number, visible: boolean): void {
    if (this.visible[index] === undefined || this.visible[index] === visible) return;
    this.visible[index] = visible;
    // A history drawing has several traces per signal (min, max, the ring's newest): redraw.
    if (this.view.kind !== "ring") this.needsRebuild = true;
    else if (this.onPicture) this.drawPicture();
    else if (this.el !== null && this.plotlyMounted) this.backend.restyle(this.el, { visible }, [index]);
    else this.needsRebuild = true;
  }

  isTraceVisible(index: number): boolean {
    return this.visible[index] ?? false;
  }

  /** Draw the whole view again at the next update (the element or its picture changed size). */
  redraw(): void {
    this.needsRebuild = true;
  }

  /** Whether an update would do anything now. */
  hasWork(): boolean {
    if (this.el === null) return false;
    // A history view: only when an answer came (or a redraw was asked for), never per frame.
    if (this.view.kind !== "ring") return this.needsRebuild;
    if (this.paused) return false;
    return this.needsRebuild || this.ringView.hasNew() || this.backfill?.undecided(this.window_ms) === true;
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
    // The first frames after a drawing of an empty ring: whole again, to ask the recording for
    // the window's start (lib/plots/plotBackfill.ts).
    if (this.needsRebuild || this.ringView.fellBehind() || this.backfill?.undecided(this.window_ms) === true) {
      this.rebuild(el);
      this.lastUpdate_ms = now_ms;
      return true;
    }
    const chunk = this.ringView.takeNew();
    if (chunk === null) return false;
    if (this.onPicture && this.picture !== null) {
      this.picture.extend(chunk.xs, chunk.ys, this.maxPoints);
      this.drawPicture();
    } else {
      const xs = chunk.xs[0] ?? [];
      const axes = this.liveTicks
        ? { xaxis: ticksBefore(xs[xs.length - 1] ?? Number.NaN, this.window_ms, this.areaWidth_px, this.options.fontSize_px) }
        : undefined;
      this.plotlyIn(el).extendTraces(el, { x: chunk.xs, y: chunk.ys }, this.traceIndices, this.maxPoints, axes);
    }
    this.points = Math.min(this.maxPoints, this.points + chunk.buckets * POINTS_PER_BUCKET);
    this.lastUpdate_ms = now_ms;
    this.updates++;
    this.mark();
    return true;
  }

  protected rebuild(el: HTMLElement): void {
    if (this.view.kind !== "ring") {
      this.drawHistory(el);
      return;
    }
    const onPicture = this.picture !== null && !this.interactive;
    if (!onPicture && !this.plotlyReady()) {
      // Drawn when Plotly comes (`plotlyCame`).
      this.needsRebuild = true;
      return;
    }
    this.needsRebuild = false;
    this.tzShift_ms = axisShift_ms(Date.now());
    this.ringView.shift_ms = this.tzShift_ms;
    this.backfill?.askIfShort(this.window_ms);
    const ringChunk = this.ringView.rebuild();
    const chunk = this.backfill?.prepend(ringChunk, this.traces, this.tzShift_ms, this.window_ms) ?? ringChunk;
    this.points = Math.min(this.maxPoints, chunk?.xs[0]?.length ?? 0);
    // `uirevision` keeps a zoom across a redraw, but not across a change of config (Plotly
    // starts over then, as when the plot turns static or interactive): carry it explicitly.
    const kept = this.drawnRevision === this.revision ? this.currentZoom() : {};
    // A step's x range (zoomRing), with the person's y zoom kept.
    const zoom = this.stepZoom !== null ? { ...kept, xaxis: this.stepZoom } : kept;
    this.stepZoom = null;
    this.drawnRevision = this.revision;
    if (this.picture !== null && onPicture) {
      this.pictureZoom = zoom;
      this.picture.reset(chunk?.xs ?? [], chunk?.ys ?? []);
      this.showPicture(true);
      this.drawPicture();
    } else {
      const data = this.traces.map((trace, i) => ({
        ...traceStyle(trace, i, this.visible[i] ?? true, this.options.readOnly),
        x: chunk?.xs[i] ?? [],
        y: chunk?.ys[i] ?? [],
      }));
      this.showPicture(false);
      this.plotlyIn(el).react(el, data, this.layout(zoom), plotConfig(this.interactive));
    }
    this.updates++;
    this.mark();
  }

  /** The zoom in force: the picture's while it draws, else what Plotly shows. */
  protected currentZoom(): AxisRanges {
    if (this.onPicture) return this.pictureZoom;
    return this.el !== null ? this.backend.zoomedAxes(this.el) : {};
  }

  protected showPicture(on: boolean): void {
    if (this.picture === null || on === this.onPicture) return;
    this.onPicture = on;
    this.picture.show(on);
    if (this.el !== null) this.el.dataset.renderer = on ? "canvas" : "plotly";
  }

  /** Draw the picture with its points and zoom; its x range on the element (ms since the epoch). */
  protected drawPicture(): void {
    const drawn = this.picture?.draw(pictureDrawing(this.pictureZoom, this.visible)) ?? null;
    if (drawn === null || this.el === null) return;
    this.el.dataset.xFrom = String(drawn[0] + this.tzShift_ms);
    this.el.dataset.xTo = String(drawn[1] + this.tzShift_ms);
  }

  /**
   * Draw the view's range from the recording: the newest answer as min/max envelopes, and what
   * the ring holds after the answer's newest frame (not yet recorded, or no recording at all)
   * as a line per signal; the events of the range as dotted lines on the time axis.
   */
  protected drawHistory(el: HTMLElement): void {
    if (!this.plotlyReady()) {
      // The recording is drawn by Plotly only: when it comes (the picture stays meanwhile).
      this.needsRebuild = true;
      return;
    }
    this.needsRebuild = false;
    this.showPicture(false);
    this.tzShift_ms = axisShift_ms(Date.now());
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
    this.plotlyIn(el).react(el, drawing.traces, layout, plotConfig(this.interactive));
    this.updates++;
    el.dataset.from = String(range_s.from_s);
    el.dataset.to = String(range_s.to_s);
    el.dataset.frames = String(data?.answer.frames ?? 0);
    this.mark();
    this.tell();
  }

  protected mark(): void {
    if (this.el === null) return;
    this.onDrawn?.();
    this.el.dataset.points = String(this.points);
    this.el.dataset.paused = this.paused ? "true" : "false";
    this.el.dataset.windowMs = String(this.window_ms);
    this.el.dataset.interactive = this.interactive ? "true" : "false";
    this.el.dataset.zoomed = this.zoomed ? "true" : "false";
    this.el.dataset.view = this.view.kind;
  }

  /** Plotly's layout now, with `zoom`'s axis ranges (lib/plots/plotAppearance.ts). */
  protected layout(zoom: AxisRanges = {}): Record<string, unknown> {
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
