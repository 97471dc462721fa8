/**
 * Layer: the 3D view's data, independent of React and of three.js (plain TypeScript).
 *
 * Reads the arm's joint positions from the live sample ring (the same ring the plots read; the
 * samples never pass through React), works out every link's frame by the arm's forward
 * kinematics (armKinematics.ts), and keeps the flange's path over the last `trail_ms` in a fixed
 * ring (memory allocated once).
 *
 * Frames arrive in batches (the service sends one WebSocket message per 50 ms by default), so
 * drawing the newest sample would move the arm in 20 steps a second however fast the display.
 * The pose drawn is instead played back `delay_ms` behind the newest sample on a clock that runs
 * with the browser's, interpolated between the two samples around it: the arm moves on every
 * animation frame, a fixed `delay_ms` after the robot did. The view asks `update()` and
 * `poseAt()` once per animation frame and redraws only when the pose moved.
 */
import { ArmChain, type Transform } from "./armKinematics";
import type { ChannelMap } from "../plots/plots";
import type { SampleRing } from "../stream/ringBuffer";

/** The flange's path over this long is drawn behind it. */
export const DEFAULT_TRAIL_MS = 5_000;

/** How far behind the newest sample the pose is played back (two of the service's batches). */
export const DEFAULT_PLAYBACK_DELAY_MS = 100;

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
   * The points of the `window_ms` up to `until_ms` (the newest point by default), oldest first,
   * into `out` (x, y, z each; at least capacity × 3 long). Returns how many.
   */
  copyInto(out: Float32Array, until_ms = Infinity): number {
    const n = this.size;
    if (n === 0) return 0;
    let last = this.written - 1;
    while (last >= this.written - n && (this.times_ms[last % this.capacity] as number) > until_ms) last--;
    if (last < this.written - n) return 0;
    const end = this.times_ms[last % this.capacity] as number;
    let first = this.written - n;
    while (first < last && (this.times_ms[first % this.capacity] as number) < end - this.window_ms) first++;
    let k = 0;
    for (let seq = first; seq <= last; seq++) {
      const slot = seq % this.capacity;
      out[k * 3] = this.xyz[slot * 3] as number;
      out[k * 3 + 1] = this.xyz[slot * 3 + 1] as number;
      out[k * 3 + 2] = this.xyz[slot * 3 + 2] as number;
      k++;
    }
    return k;
  }
}

/** The length of the path of `count` points of x, y, z in `xyz` (in the points' unit). */
export function pathLength(xyz: Float32Array, count: number): number {
  let length = 0;
  for (let k = 1; k < count; k++) {
    const i = k * 3;
    length += Math.hypot(
      (xyz[i] as number) - (xyz[i - 3] as number),
      (xyz[i + 1] as number) - (xyz[i - 2] as number),
      (xyz[i + 2] as number) - (xyz[i - 1] as number),
    );
  }
  return length;
}

/** The arm's pose and flange path, fed from the sample ring. */
export class RobotPoseFeed {
  readonly chain: ArmChain;
  /** Base frame then each link's frame for the newest sample (m, base frame). */
  readonly frames: Transform[];
  readonly trail: TcpTrail;
  /** The joint angles of the pose drawn (degrees; `frames` is their forward kinematics). */
  readonly drawn_deg: Float64Array;
  private readonly ring: SampleRing;
  private readonly jointChannels: readonly number[];
  private readonly joints_deg: Float64Array;
  private readonly after_deg: Float64Array;
  private readonly scratch: Transform[];
  private readonly delay_ms: number;
  private readSeq = 0;
  /** The ring time of the pose drawn, and the browser time it was worked out at. */
  private playback_ms: number | null = null;
  private playbackAt_ms = 0;
  private drawn_ms: number | null = null;
  /** Whether a pose has been computed yet. */
  hasPose = false;
  /** Samples taken from the ring, for tests and the benchmark. */
  samples = 0;

  constructor(
    chain: ArmChain,
    ring: SampleRing,
    channels: ChannelMap,
    trail_ms = DEFAULT_TRAIL_MS,
    maxRate_hz = 1000,
    delay_ms = DEFAULT_PLAYBACK_DELAY_MS,
  ) {
    this.chain = chain;
    this.ring = ring;
    const n = chain.jointCount;
    this.jointChannels = Array.from({ length: n }, (_, i) => channels.channelOf("joint_position", i));
    this.joints_deg = new Float64Array(n);
    this.after_deg = new Float64Array(n);
    this.drawn_deg = new Float64Array(n);
    this.delay_ms = delay_ms;
    this.frames = chain.newFrames();
    this.scratch = chain.newFrames();
    this.trail = new TcpTrail(Math.max(2, Math.ceil((trail_ms / 1000) * maxRate_hz)), trail_ms);
  }

  /** Take what the ring received since the last call into the path; true when there was any. */
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
    this.readSeq = end;
    return moved;
  }

  /**
   * The pose at browser time `now_ms` (performance.now()) into `frames`: played back `delay_ms`
   * behind the newest sample, interpolated; true when it differs from the pose last worked out.
   */
  poseAt(now_ms: number): boolean {
    const ring = this.ring;
    const newest = ring.newestTime();
    if (newest === null || ring.size === 0) return false;
    const wanted = newest - this.delay_ms;
    let t = this.playback_ms === null ? wanted : this.playback_ms + (now_ms - this.playbackAt_ms);
    // Never ahead of the data; far behind (a stall, a hidden tab, clock drift): catch up at once.
    if (t > newest) t = newest;
    if (t < wanted - 2 * this.delay_ms) t = wanted;
    this.playback_ms = t;
    this.playbackAt_ms = now_ms;
    if (t === this.drawn_ms) return false;
    const after = Math.min(ring.firstSeqAtOrAfter(t), ring.endSeq - 1);
    if (!this.readJoints(after)) return false;
    const before = after - 1;
    if (before >= ring.oldestSeq) {
      const t0 = ring.timeAt(before);
      const t1 = ring.timeAt(after);
      const f = t1 > t0 ? Math.min(1, Math.max(0, (t - t0) / (t1 - t0))) : 1;
      this.after_deg.set(this.joints_deg);
      if (f < 1 && this.readJoints(before)) {
        // joints_deg now holds `before`; blend towards `after` (kept in after_deg).
        for (let i = 0; i < this.joints_deg.length; i++) {
          const a = this.joints_deg[i] as number;
          this.joints_deg[i] = a + ((this.after_deg[i] as number) - a) * f;
        }
      } else {
        this.joints_deg.set(this.after_deg);
      }
    }
    this.chain.forward(this.joints_deg, this.frames);
    this.drawn_deg.set(this.joints_deg);
    this.drawn_ms = t;
    this.hasPose = true;
    return true;
  }

  /** The path up to the pose drawn, ending at its flange, into `out`; returns the point count. */
  trailInto(out: Float32Array): number {
    if (this.drawn_ms === null) return 0;
    let n = this.trail.copyInto(out, this.drawn_ms);
    const flange = this.frames[this.frames.length - 1] as Transform;
    if (n * 3 + 3 <= out.length) {
      out[n * 3] = flange[3] as number;
      out[n * 3 + 1] = flange[7] as number;
      out[n * 3 + 2] = flange[11] as number;
      n++;
    }
    return n;
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
