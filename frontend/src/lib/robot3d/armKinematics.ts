/**
 * Layer: pure arm geometry (no React, no DOM, no three.js).
 *
 * Forward kinematics of the arms in `src/generated/arms.ts` (generated from the backend's
 * `cobot_hmi/arms.py`, the one place the URDF chains live), the same composition the emulator
 * uses (docs/emulator.md, "Reference facts the model follows"): each joint is its URDF origin
 * (translation, then `Rz(yaw)·Ry(pitch)·Rx(roll)`) followed by a rotation about its local z.
 * A rigid transform is 12 numbers, row-major `(R | p)`; the results go into a caller's buffer,
 * so a frame drawn 60 times a second allocates nothing.
 */
import { ARMS, DEFAULT_ARM, ARM_NAMES, type Arm, type ArmName, type Vec3 } from "../../generated/arms";

/** 3×4 rigid transform, row-major: r00 r01 r02 px r10 r11 r12 py r20 r21 r22 pz. */
export type Transform = Float64Array;

const RAD_PER_DEG = Math.PI / 180;

export function identity(): Transform {
  return Float64Array.of(1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0);
}

/** A URDF `<origin xyz rpy>`. */
export function fromRpy(xyz: Vec3, rpy: Vec3): Transform {
  const [roll, pitch, yaw] = rpy;
  const cr = Math.cos(roll);
  const sr = Math.sin(roll);
  const cp = Math.cos(pitch);
  const sp = Math.sin(pitch);
  const cy = Math.cos(yaw);
  const sy = Math.sin(yaw);
  return Float64Array.of(
    cy * cp,
    cy * sp * sr - sy * cr,
    cy * sp * cr + sy * sr,
    xyz[0],
    sy * cp,
    sy * sp * sr + cy * cr,
    sy * sp * cr - cy * sr,
    xyz[1],
    -sp,
    cp * sr,
    cp * cr,
    xyz[2],
  );
}

/** out = a · b (out may not be a or b). */
export function compose(a: Transform, b: Transform, out: Transform): Transform {
  for (let r = 0; r < 3; r++) {
    const a0 = a[4 * r] as number;
    const a1 = a[4 * r + 1] as number;
    const a2 = a[4 * r + 2] as number;
    for (let c = 0; c < 4; c++) {
      out[4 * r + c] = a0 * (b[c] as number) + a1 * (b[4 + c] as number) + a2 * (b[8 + c] as number);
    }
    out[4 * r + 3] = (out[4 * r + 3] as number) + (a[4 * r + 3] as number);
  }
  return out;
}

/** out = a · Rz(q). */
function rotZInto(a: Transform, q_rad: number, out: Transform): void {
  const c = Math.cos(q_rad);
  const s = Math.sin(q_rad);
  for (let r = 0; r < 3; r++) {
    const a0 = a[4 * r] as number;
    const a1 = a[4 * r + 1] as number;
    out[4 * r] = a0 * c + a1 * s;
    out[4 * r + 1] = a1 * c - a0 * s;
    out[4 * r + 2] = a[4 * r + 2] as number;
    out[4 * r + 3] = a[4 * r + 3] as number;
  }
}

/** An arm's forward kinematics with its constant origin transforms worked out once. */
export class ArmChain {
  readonly arm: Arm;
  private readonly origins: Transform[];
  private readonly scratch = identity();

  constructor(arm: Arm) {
    this.arm = arm;
    this.origins = arm.joints.map((j) => fromRpy(j.originXyz_m, j.originRpy_rad));
  }

  get jointCount(): number {
    return this.origins.length;
  }

  /**
   * Frames of the base and of each moving link (after its joint's rotation), J1 first, into
   * `frames` (jointCount + 1 transforms; frames[0] is the base). The flange is the last one.
   */
  forward(joints_deg: ArrayLike<number>, frames: Transform[]): void {
    const base = frames[0];
    if (base === undefined || frames.length < this.origins.length + 1) throw new Error("frames: one more than the joints");
    base.set(IDENTITY);
    for (let i = 0; i < this.origins.length; i++) {
      const parent = frames[i] as Transform;
      compose(parent, this.origins[i] as Transform, this.scratch);
      rotZInto(this.scratch, (joints_deg[i] ?? 0) * RAD_PER_DEG, frames[i + 1] as Transform);
    }
  }

  /** Buffers for `forward`. */
  newFrames(): Transform[] {
    return Array.from({ length: this.origins.length + 1 }, () => identity());
  }

  /** The flange (TCP without a tool) in mm, base frame. */
  tcpPosition_mm(joints_deg: ArrayLike<number>): [number, number, number] {
    const frames = this.newFrames();
    this.forward(joints_deg, frames);
    const f = frames[frames.length - 1] as Transform;
    return [(f[3] as number) * 1000, (f[7] as number) * 1000, (f[11] as number) * 1000];
  }
}

const IDENTITY = identity();

/** The frame's origin (m). */
export function originOf(t: Transform): [number, number, number] {
  return [t[3] as number, t[7] as number, t[11] as number];
}

/**
 * The arm a robot is, from its model as the service reports it (its identity's product name,
 * e.g. "Doosan M0609 (emulated)"); the default arm when the name is unknown or names no arm.
 */
export function armNameOf(model: string | null | undefined): { readonly name: ArmName; readonly known: boolean } {
  if (model !== null && model !== undefined) {
    const upper = model.toUpperCase();
    for (const name of ARM_NAMES) if (upper.includes(name)) return { name, known: true };
  }
  return { name: DEFAULT_ARM, known: false };
}

export function armByName(name: ArmName): Arm {
  return ARMS[name];
}
