/**
 * Layer: a live plot's views of the recording, their data side (plain TypeScript; no DOM, no
 * Plotly, no React).
 *
 * A plot of the panel (lib/plots/plotting.ts) shows either its ring or a view of the recording: a long
 * moving window or a fixed range of the past (docs/architecture.md "Plots: from the ring into
 * the recording"). This module is what such a view needs besides the plot's state: which range
 * to ask for and how many points, the fetching (`PlotRecording`: debounced, a stale answer
 * dropped, through lib/plots/historyView.ts's `RangeLoader`), how often a moving window asks again,
 * and the traces of a drawing (the answer's envelopes, and the ring's newest samples the
 * recording has not written yet). Which view is shown, and when to draw, is `LivePlot`'s.
 * Must not import lib/plots/plotting.ts, Plotly or React.
 */
import { MinMaxBucketer } from "./decimate";
import {
  RangeLoader,
  browserTimer,
  bucketsForWidth,
  envelopeTraceSets,
  newestRecorded,
  type FetchRange,
  type HistoryEvent,
  type RangeData,
  type TimeRange,
  type Timer,
} from "./historyView";
import { plotAreaWidth_px, traceStyle } from "./plotAppearance";
import type { PlotSpec, TraceInfo } from "./plots";
import type { SpanMs } from "./plotSteps";
import type { SampleRing } from "../stream/ringBuffer";

/** Where a plot reads the recording of its fields (lib/history/historyApi.ts in the panel, a fake in tests). */
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

/** How long a moving window of `span_ms` drawn with `points` buckets waits to ask again (ms). */
export function movingRefresh_ms(span_ms: number, points: number): number {
  return Math.min(MOVING_REFRESH_MAX_MS, Math.max(MOVING_REFRESH_MIN_MS, span_ms / points));
}

/**
 * Buckets to ask for: about one per pixel of the plotting area of an element `width_px` wide
 * (undefined: not known, a default).
 */
export function pointsWanted(spec: PlotSpec, width_px: number | undefined): number {
  return bucketsForWidth(plotAreaWidth_px(spec, width_px ?? Number.NaN));
}

/**
 * The range `view` asks for (ms since the epoch): a fixed view's own; a moving one's span (the
 * ring's: `window_ms`) ending at `now_ms`.
 */
export function rangeWanted(view: PlotView, now_ms: number, window_ms: number): SpanMs {
  if (view.kind === "fixed") return { from: view.from_ms, to: view.to_ms };
  return { from: now_ms - (view.kind === "moving" ? view.span_ms : window_ms), to: now_ms };
}

/**
 * Now on the frames' time axis: the ring's newest frame (`newest_ms`) while frames come, else
 * the clock. The receive times are the service's clock; the browser's may differ by a little.
 */
export function nowOnFrames(newest_ms: number | null, clock_ms: number): number {
  return newest_ms !== null && Math.abs(clock_ms - newest_ms) < 30_000 ? newest_ms : clock_ms;
}

/** What a plot does when the recording answers, fails, or a moving window's refresh is due. */
export interface RecordingListener {
  answered(data: RangeData): void;
  failed(reason: string): void;
  refreshDue(): void;
}

/**
 * A plot's requests to the recording: a range at a time (debounced unless `immediate`; a newer
 * request aborts the one in flight, whose answer is never delivered) and one pending refresh of
 * a moving window.
 */
export class PlotRecording {
  private readonly loader: RangeLoader;
  private readonly timer: Timer;
  private readonly listener: RecordingListener;
  private refreshHandle: unknown = null;
  /** The refresh's timer callback, made once. */
  private readonly refreshFired = (): void => {
    this.refreshHandle = null;
    this.listener.refreshDue();
  };

  constructor(source: PlotHistorySource, listener: RecordingListener) {
    this.listener = listener;
    this.timer = source.timer ?? browserTimer;
    this.loader = new RangeLoader(
      source.fetchRange,
      (data) => listener.answered(data),
      (reason) => listener.failed(reason),
      source.debounce_ms,
      this.timer,
    );
  }

  /** Ask for `range_ms` (ms since the epoch) in `points` buckets. */
  request(range_ms: SpanMs, points: number, immediate: boolean): void {
    this.loader.request({ from_s: range_ms.from / 1000, to_s: range_ms.to / 1000 }, points, immediate);
  }

  /** No request waits or is in flight any more (nothing more is delivered). */
  stopRequests(): void {
    this.loader.stop();
  }

  /** A moving window of `span_ms` in `points` buckets asks again when about a new bucket has filled. */
  scheduleRefresh(span_ms: number, points: number): void {
    this.clearRefresh();
    this.refreshHandle = this.timer.set(this.refreshFired, movingRefresh_ms(span_ms, points));
  }

  clearRefresh(): void {
    if (this.refreshHandle !== null) this.timer.clear(this.refreshHandle);
    this.refreshHandle = null;
  }
}

/** The plot a drawing of the recording is for. */
export interface DrawnPlot {
  readonly spec: PlotSpec;
  readonly traces: readonly TraceInfo[];
  /** The signal picker's choice per trace. */
  readonly visible: readonly boolean[];
  readonly readOnly: boolean;
  readonly ring: SampleRing;
  /** The ring's channel of each trace. */
  readonly ringChannels: readonly number[];
}

export interface HistoryTraces {
  readonly traces: object[];
  /** Points of the first signal (its envelope's and the ring's). */
  readonly points: number;
}

/**
 * The traces of a drawing of `range` (ms since the epoch): per signal, the newest answer's
 * min/max envelopes (none before the first answer), and what the ring holds after the answer's
 * newest recorded frame (not yet recorded, or no recording at all) as a line, in `points`
 * buckets. `shift_ms` is subtracted from every time (Plotly shows numeric dates in UTC).
 */
export function historyTraces(
  plot: DrawnPlot,
  data: RangeData | null,
  range: SpanMs,
  points: number,
  shift_ms: number,
): HistoryTraces {
  const { from, to } = range;
  const sets = data !== null ? envelopeTraceSets(data.answer, plot.spec, shift_ms) : plot.traces.map(() => []);
  const recorded_s = data !== null ? newestRecorded(data.answer) : null;
  const tailFrom = Math.max(from, recorded_s === null ? -Infinity : recorded_s * 1000 + 1e-3);
  const tail = new MinMaxBucketer(plot.ringChannels, Math.max((to - from) / points, 1), points, (t) => t - shift_ms);
  tail.feedRing(plot.ring, plot.ring.firstSeqAtOrAfter(tailFrom), plot.ring.firstSeqAtOrAfter(to));
  const chunk = tail.take();
  const traces: object[] = [];
  let drawnPoints = 0;
  plot.traces.forEach((trace, i) => {
    const visible = plot.visible[i] ?? true;
    const own = sets[i] ?? [];
    for (const t of own) traces.push({ ...t, visible });
    const tailX = chunk?.xs[i] ?? [];
    traces.push({ ...traceStyle(trace, i, visible, plot.readOnly), x: tailX, y: chunk?.ys[i] ?? [], showlegend: false });
    if (i === 0) drawnPoints = ((own[0] as { x?: unknown[] } | undefined)?.x?.length ?? 0) + tailX.length;
  });
  return { traces, points: drawnPoints };
}
