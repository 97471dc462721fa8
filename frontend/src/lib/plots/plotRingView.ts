/**
 * Layer: a live plot's ring view, its data side (plain TypeScript; no DOM, no Plotly, no React).
 *
 * The ring view (docs/architecture.md "Plots: from the ring into the recording") shows the
 * moving window of 10 s, 30 s or 2 min from the sample ring alone: rebuilt whole (the window's
 * min/max buckets) when it is drawn anew, then appended with the buckets completed since. This
 * module is that reading of the ring and what the view holds: where its window starts (the
 * ring's oldest frame while the ring holds less, just after the page opened), the range a paused
 * picture froze with, a range kept within what it holds. Which view is shown, and when to draw,
 * is `LivePlot`'s (lib/plots/plotting.ts). Must not import lib/plots/plotting.ts, Plotly or React.
 */
import { bucketWidthMs, MinMaxBucketer, type TraceChunk } from "./decimate";
import { BUCKETS_PER_WINDOW } from "./plotAppearance";
import type { SpanMs } from "./plotSteps";
import type { SampleRing } from "../stream/ringBuffer";

export class RingView {
  private readonly ring: SampleRing;
  private readonly channels: readonly number[];
  private window_ms: number;
  private bucketer: MinMaxBucketer;
  /** The ring's samples before this sequence number are drawn (or bucketed). */
  private readSeq = 0;
  /** The range of the last rebuild (a paused picture shows it). */
  private drawnFrom_ms: number | null = null;
  private drawnTo_ms: number | null = null;
  /**
   * Subtracted from every sample time for its x value: Plotly shows numeric dates in UTC, so
   * the browser's time-zone offset makes them local time of day.
   */
  shift_ms = 0;

  constructor(ring: SampleRing, channels: readonly number[], window_ms: number) {
    this.ring = ring;
    this.channels = channels;
    this.window_ms = window_ms;
    this.bucketer = this.newBucketer();
  }

  get windowMs(): number {
    return this.window_ms;
  }

  setWindow(window_ms: number): void {
    this.window_ms = window_ms;
  }

  /** Samples arrived since the last reading. */
  hasNew(): boolean {
    return this.readSeq !== this.ring.endSeq;
  }

  /** The ring overwrote samples not yet read: only a rebuild draws the window whole again. */
  fellBehind(): boolean {
    return this.readSeq < this.ring.oldestSeq;
  }

  /** The ring's newest sample time (ms since the epoch), or null while empty. */
  newestTime(): number | null {
    return this.ring.newestTime();
  }

  /** The whole window's buckets, read anew (the next `takeNew` continues from there). */
  rebuild(): TraceChunk | null {
    this.bucketer = this.newBucketer();
    const newest = this.ring.newestTime();
    this.drawnTo_ms = newest;
    this.drawnFrom_ms = newest === null ? null : this.start_ms(newest);
    const end = this.ring.endSeq;
    if (newest !== null) this.bucketer.feedRing(this.ring, this.ring.firstSeqAtOrAfter(newest - this.window_ms), end);
    this.readSeq = end;
    return this.bucketer.take();
  }

  /** The buckets completed since the last reading, or null when none completed. */
  takeNew(): TraceChunk | null {
    const end = this.ring.endSeq;
    if (this.readSeq === end) return null;
    this.bucketer.feedRing(this.ring, this.readSeq, end);
    this.readSeq = end;
    return this.bucketer.take();
  }

  /** The range of the last rebuild (ms since the epoch), or null before any with data. */
  drawnRange(): SpanMs | null {
    return this.drawnFrom_ms === null || this.drawnTo_ms === null ? null : { from: this.drawnFrom_ms, to: this.drawnTo_ms };
  }

  /** The oldest time the view draws: its window back from the newest frame, or the ring's oldest. */
  heldFrom_ms(): number | null {
    const newest = this.ring.newestTime();
    return newest === null ? null : this.start_ms(newest);
  }

  /**
   * Where a ring view ending at `to_ms` starts: its window back, or the ring's oldest frame while
   * the ring holds less (just after the page opened), as the autoranged axis shows it.
   */
  start_ms(to_ms: number): number {
    const from = to_ms - this.window_ms;
    if (this.ring.newestTime() === null) return from;
    const oldest = this.ring.timeAt(this.ring.oldestSeq);
    return oldest < to_ms ? Math.max(from, oldest) : from;
  }

  /** `range` moved to start no earlier than the view holds; "live" once it covers it all. */
  within(range: SpanMs, now_ms: number): SpanMs | "live" | null {
    const held = this.heldFrom_ms();
    if (held === null) return null;
    if (range.from >= held) return range;
    const to = Math.min(now_ms, held + (range.to - range.from));
    return to >= now_ms ? "live" : { from: held, to };
  }

  private newBucketer(): MinMaxBucketer {
    return new MinMaxBucketer(
      this.channels,
      bucketWidthMs(this.window_ms, BUCKETS_PER_WINDOW),
      BUCKETS_PER_WINDOW,
      (t) => t - this.shift_ms,
    );
  }
}
