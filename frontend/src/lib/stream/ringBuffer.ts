/**
 * Layer: pure data structure (no React, no DOM, no network).
 *
 * A fixed-capacity ring of time-stamped samples, one typed array per channel. Samples live here,
 * outside React state: the WebSocket writes, the plot tick reads. Memory is allocated once, so a
 * panel or kiosk left open for days does not grow. Sequence numbers count every sample ever
 * pushed; a reader keeps the sequence number it has read up to and learns from `oldestSeq` when
 * it fell behind and lost samples.
 */
export class SampleRing {
  readonly capacity: number;
  readonly channelCount: number;
  private readonly times_ms: Float64Array;
  private readonly values: Float32Array[];
  private written = 0;

  constructor(capacity: number, channelCount: number) {
    if (!Number.isInteger(capacity) || capacity < 1) throw new Error("capacity must be ≥ 1");
    if (!Number.isInteger(channelCount) || channelCount < 0) throw new Error("bad channel count");
    this.capacity = capacity;
    this.channelCount = channelCount;
    this.times_ms = new Float64Array(capacity);
    this.values = Array.from({ length: channelCount }, () => new Float32Array(capacity));
  }

  /** Sequence number the next pushed sample gets (= number of samples ever pushed). */
  get endSeq(): number {
    return this.written;
  }

  /** Sequence number of the oldest sample still held. */
  get oldestSeq(): number {
    return Math.max(0, this.written - this.capacity);
  }

  get size(): number {
    return this.written - this.oldestSeq;
  }

  /**
   * Append one sample. `row[c]` is channel c's value (NaN for "no value"); missing entries are
   * stored as NaN. Times must not go backwards (a reader relies on it for binary search); an
   * older time is clamped to the newest one.
   */
  push(time_ms: number, row: ArrayLike<number>): void {
    const slot = this.written % this.capacity;
    const newest = this.written > 0 ? this.timeAt(this.written - 1) : -Infinity;
    this.times_ms[slot] = time_ms < newest ? newest : time_ms;
    for (let c = 0; c < this.channelCount; c++) {
      const column = this.values[c] as Float32Array;
      const v = c < row.length ? (row[c] as number) : Number.NaN;
      column[slot] = v;
    }
    this.written++;
  }

  /** Time of sample `seq` (must be in [oldestSeq, endSeq)). */
  timeAt(seq: number): number {
    return this.times_ms[seq % this.capacity] as number;
  }

  /** Value of channel `channel` of sample `seq` (must be in [oldestSeq, endSeq)). */
  valueAt(channel: number, seq: number): number {
    const column = this.values[channel];
    if (column === undefined) return Number.NaN;
    return column[seq % this.capacity] as number;
  }

  /** The first held sequence number whose time is ≥ `time_ms` (endSeq if none). */
  firstSeqAtOrAfter(time_ms: number): number {
    let lo = this.oldestSeq;
    let hi = this.written;
    while (lo < hi) {
      const mid = (lo + hi) >>> 1;
      if (this.timeAt(mid) < time_ms) lo = mid + 1;
      else hi = mid;
    }
    return lo;
  }

  /** Time of the newest sample, or null when empty. */
  newestTime(): number | null {
    return this.written > 0 ? this.timeAt(this.written - 1) : null;
  }

  clear(): void {
    this.written = 0;
  }
}
