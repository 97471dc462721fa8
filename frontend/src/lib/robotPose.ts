/**
 * Layer: the 3D view's data, independent of React and of three.js (plain TypeScript).
 *
 * Reads the arm's joint positions from the live sample ring (the same ring the plots read; the
 * samples never pass through React), works out every link's frame by the arm's forward
 * kinematics (armKinematics.ts) for the newest sample, and keeps the flange's path over the last
 * `trail_ms` in a fixed ring (memory allocated once). The view asks `update()` once per
 * animation frame and redraws only when it says something moved.
 */
import { ArmChain, type Transform } from "./armKinematics";
import type { ChannelMap } from "./plots";
import type { SampleRing } from "./ringBuffer";

/** The flange's path over this long is drawn behind it. */
export const DEFAULT_TRAIL_MS = 5_000;

/** A fixed-capacity path of time-stamped points; points older than the window are dropped. */
export class TcpTrail {
  readonly capacity: number;
  readonly window_ms: number;
  private readonly times_ms: Float64Array;
  private readonly xyz: Float32Array;
  private written = 0;

  constructor(capacity: number, window_ms: number) {
    if (!Number.isInteger(capacity) || capacity < 2) throw new Error("capacity must be ≥ 2");
    this.capacity = capacity;
    this.window_ms = window_ms;
    this.times_ms = new Float64Array(capacity);
    this.xyz = new Float32Array(capacity * 3);
  }

  get size(): number {
    return Math.min(this.written, this.capacity);
  }

  push(time_ms: number, x: number, y: number, z: number): void {
    const slot = this.written % this.capacity;
    this.times_ms[slot] = time_ms;
    this.xyz[slot * 3] = x;
    this.xyz[slot * 3 + 1] = y;
    this.xyz[slot * 3 + 2] = z;
    this.written++;
  }

  clear(): void {
    this.written = 0;
  }

  /**
   * The points no older than `window_ms` before the newest, oldest first, into `out` (x, y, z
   * each; at least capacity × 3 long). Returns how many.
   */
  copyInto(out: Float32Array): number {
    const n = this.size;
    if (n === 0) return 0;
    const newest = this.times_ms[(this.written - 1) % this.capacity] as number;
    let first = this.written - n;
    while (first < this.written - 1 && (this.times_ms[first % this.capacity] as number) < newest - this.window_ms) first++;
    let k = 0;
    for (let seq = first; seq < this.written; seq++) {
      const slot = seq % this.capacity;
      out[k * 3] = this.xyz[slot * 3] as number;
      out[k * 3 + 1] = this.xyz[slot * 3 + 1] as number;
      out[k * 3 + 2] = this.xyz[slot * 3 + 2] as number;
      k++;
    }
    return k;
  }
}

/** The arm's pose and flange path, fed from the sample ring. */
export class RobotPoseFeed {
  readonly chain: ArmChain;
  /** Base frame then each link's frame for the newest sample (m, base frame). */
  readonly frames: Transform[];
  readonly trail: TcpTrail;
  private readonly ring: SampleRing;
  private readonly jointChannels: readonly number[];
  private readonly joints_deg: Float64Array;
  private readonly scratch: Transform[];
  private readSeq = 0;
  /** Whether a pose has been computed yet. */
  hasPose = false;
  /** Samples taken from the ring, for tests and the benchmark. */
  samples = 0;

  constructor(chain: ArmChain, ring: SampleRing, channels: ChannelMap, trail_ms = DEFAULT_TRAIL_MS, maxRate_hz = 1000) {
    this.chain = chain;
    this.ring = ring;
    const n = chain.jointCount;
    this.jointChannels = Array.from({ length: n }, (_, i) => channels.channelOf("joint_position", i));
    this.joints_deg = new Float64Array(n);
    this.frames = chain.newFrames();
    this.scratch = chain.newFrames();
    this.trail = new TcpTrail(Math.max(2, Math.ceil((trail_ms / 1000) * maxRate_hz)), trail_ms);
  }

  /** Take what the ring received since the last call; true when the pose or path changed. */
  update(): boolean {
    const ring = this.ring;
    const end = ring.endSeq;
    if (end === this.readSeq) return false;
    const newest = ring.newestTime();
    if (newest === null) return false;
    // Only what the path still shows: after a long pause (a hidden tab), not the whole ring.
    const from = Math.max(this.readSeq, ring.oldestSeq, ring.firstSeqAtOrAfter(newest - this.trail.window_ms));
    if (from > this.readSeq) this.trail.clear();
    let moved = false;
    for (let seq = from; seq < end; seq++) {
      if (!this.readJoints(seq)) continue; // no joint values in this frame (NaN): skipped
      this.chain.forward(this.joints_deg, this.scratch);
      const flange = this.scratch[this.scratch.length - 1] as Transform;
      this.trail.push(ring.timeAt(seq), flange[3] as number, flange[7] as number, flange[11] as number);
      this.samples++;
      moved = true;
    }
    // The pose drawn is the newest sample's that had joint values.
    if (moved) {
      for (let i = 0; i < this.frames.length; i++) (this.frames[i] as Transform).set(this.scratch[i] as Transform);
      this.hasPose = true;
    }
    this.readSeq = end;
    return moved;
  }

  private readJoints(seq: number): boolean {
    for (let i = 0; i < this.jointChannels.length; i++) {
      const v = this.ring.valueAt(this.jointChannels[i] as number, seq);
      if (!Number.isFinite(v)) return false;
      this.joints_deg[i] = v;
    }
    return true;
  }
}
