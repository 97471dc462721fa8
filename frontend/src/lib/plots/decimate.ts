/**
 * Layer: pure decimation for plotting (no React, no DOM, no network).
 *
 * Min/max bucketing: time is cut into buckets of fixed width aligned to the epoch (so a bucket's
 * edges do not move as data streams in), and every completed bucket becomes exactly two points
 * per trace, its minimum and its maximum in time order. Peaks survive however long the window,
 * the number of points per window is fixed (two per bucket), and so `extendTraces`' `maxPoints`
 * trims a trace to exactly the window. A real gap in the data (longer than `bridge_ms`, e.g. a
 * lost connection) gives two nulls per empty bucket, which Plotly draws as a break in the line:
 * it is shown, never bridged. A short one (a late packet, or a decimated stream slower than one
 * sample per bucket) fills its empty buckets with repeats of the next real sample, so the line
 * runs straight from one real sample to the next as it would without bucketing; no value or
 * time is invented.
 */
import type { SampleRing } from "../stream/ringBuffer";

/** Points produced for each trace since the last `take()`. */
export interface TraceChunk {
  readonly xs: number[][];
  readonly ys: (number | null)[][];
  /** Number of buckets in this chunk (every trace got 2 points per bucket). */
  readonly buckets: number;
}

export const POINTS_PER_BUCKET = 2;
/** Silences up to this long are late packets or a decimated stream, not a gap to show. */
export const DEFAULT_BRIDGE_MS = 100;

export class MinMaxBucketer {
  readonly bucket_ms: number;
  private readonly channels: readonly number[];
  private readonly maxEmptyBuckets: number;
  private readonly bridge_ms: number;
  private lastTime_ms = Number.NaN;
  private readonly xOf: (time_ms: number) => number;
  private current: number | null = null;
  private readonly minV: Float64Array;
  private readonly minT: Float64Array;
  private readonly maxV: Float64Array;
  private readonly maxT: Float64Array;
  private readonly count: Uint32Array;
  private xs: number[][];
  private ys: (number | null)[][];
  private buckets = 0;

  /**
   * @param channels ring channel index of each trace, in trace order
   * @param bucket_ms bucket width
   * @param maxEmptyBuckets at most this many empty buckets are emitted for one gap (a gap longer
   *   than the window need not be drawn point by point: it scrolls the window empty)
   * @param xOf maps a sample time to the plot's x value (e.g. a time-zone shift)
   * @param bridge_ms a silence between two samples up to this long is not drawn as a gap
   */
  constructor(
    channels: readonly number[],
    bucket_ms: number,
    maxEmptyBuckets: number,
    xOf: (time_ms: number) => number = (t) => t,
    bridge_ms = DEFAULT_BRIDGE_MS,
  ) {
    if (!(bucket_ms > 0)) throw new Error("bucket width must be > 0");
    this.channels = channels;
    this.bucket_ms = bucket_ms;
    this.maxEmptyBuckets = Math.max(0, Math.floor(maxEmptyBuckets));
    this.xOf = xOf;
    this.bridge_ms = bridge_ms;
    const n = channels.length;
    this.minV = new Float64Array(n);
    this.minT = new Float64Array(n);
    this.maxV = new Float64Array(n);
    this.maxT = new Float64Array(n);
    this.count = new Uint32Array(n);
    this.xs = channels.map(() => []);
    this.ys = channels.map(() => []);
  }

  /** Feed samples [fromSeq, toSeq) of `ring`. */
  feedRing(ring: SampleRing, fromSeq: number, toSeq: number): void {
    for (let seq = fromSeq; seq < toSeq; seq++) {
      this.feed(ring.timeAt(seq), (i) => ring.valueAt(this.channels[i] as number, seq));
    }
  }

  /** Feed one sample; `valueOf(i)` is trace i's value (NaN for none). */
  feed(time_ms: number, valueOf: (trace: number) => number): void {
    const bucket = Math.floor(time_ms / this.bucket_ms);
    if (this.current === null) {
      this.startBucket(bucket);
    } else if (bucket > this.current) {
      this.emitCurrent();
      const empty = Math.min(bucket - this.current - 1, this.maxEmptyBuckets);
      if (empty > 0 && time_ms - this.lastTime_ms <= this.bridge_ms) {
        for (let k = empty; k >= 1; k--) this.emitRepeat(time_ms, valueOf);
      } else {
        for (let k = empty; k >= 1; k--) this.emitEmpty(bucket - k);
      }
      this.startBucket(bucket);
    }
    this.lastTime_ms = time_ms;
    // A sample older than the open bucket (clock step back) joins the open bucket.
    for (let i = 0; i < this.channels.length; i++) {
      const v = valueOf(i);
      if (!Number.isFinite(v)) continue;
      if (this.count[i] === 0) {
        this.minV[i] = v;
        this.maxV[i] = v;
        this.minT[i] = time_ms;
        this.maxT[i] = time_ms;
      } else {
        if (v < (this.minV[i] as number)) {
          this.minV[i] = v;
          this.minT[i] = time_ms;
        }
        if (v > (this.maxV[i] as number)) {
          this.maxV[i] = v;
          this.maxT[i] = time_ms;
        }
      }
      this.count[i] = (this.count[i] as number) + 1;
    }
  }

  /** Points of the buckets completed since the last call, or null if none completed. */
  take(): TraceChunk | null {
    if (this.buckets === 0) return null;
    const chunk: TraceChunk = { xs: this.xs, ys: this.ys, buckets: this.buckets };
    this.xs = this.channels.map(() => []);
    this.ys = this.channels.map(() => []);
    this.buckets = 0;
    return chunk;
  }

  private startBucket(bucket: number): void {
    this.current = bucket;
    this.count.fill(0);
  }

  private emitCurrent(): void {
    if (this.current === null) return;
    const start = this.current * this.bucket_ms;
    for (let i = 0; i < this.channels.length; i++) {
      const xs = this.xs[i] as number[];
      const ys = this.ys[i] as (number | null)[];
      if (this.count[i] === 0) {
        xs.push(this.xOf(start), this.xOf(start + this.bucket_ms / 2));
        ys.push(null, null);
        continue;
      }
      const tMin = this.minT[i] as number;
      const tMax = this.maxT[i] as number;
      const vMin = this.minV[i] as number;
      const vMax = this.maxV[i] as number;
      if (tMin <= tMax) {
        xs.push(this.xOf(tMin), this.xOf(tMax));
        ys.push(vMin, vMax);
      } else {
        xs.push(this.xOf(tMax), this.xOf(tMin));
        ys.push(vMax, vMin);
      }
    }
    this.buckets++;
  }

  /** An empty bucket inside a short silence: the next real sample, twice. */
  private emitRepeat(time_ms: number, valueOf: (trace: number) => number): void {
    const x = this.xOf(time_ms);
    for (let i = 0; i < this.channels.length; i++) {
      const v = valueOf(i);
      const y = Number.isFinite(v) ? v : null;
      (this.xs[i] as number[]).push(x, x);
      (this.ys[i] as (number | null)[]).push(y, y);
    }
    this.buckets++;
  }

  private emitEmpty(bucket: number): void {
    const start = bucket * this.bucket_ms;
    for (let i = 0; i < this.channels.length; i++) {
      (this.xs[i] as number[]).push(this.xOf(start), this.xOf(start + this.bucket_ms / 2));
      (this.ys[i] as (number | null)[]).push(null, null);
    }
    this.buckets++;
  }
}

/** Bucket width for a window so that it holds `bucketsPerWindow` buckets. */
export function bucketWidthMs(window_ms: number, bucketsPerWindow: number): number {
  return window_ms / bucketsPerWindow;
}
