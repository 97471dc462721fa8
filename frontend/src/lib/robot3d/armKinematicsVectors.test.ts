// The 3D view's kinematics against the golden vectors `cobot-hmi codegen` computes with the
// emulator's Python model (src/generated/armKinematicsVectors.json, codegen/arm_vectors.py): the
// TCP's position and orientation and every joint frame's origin, for every arm, within the
// file's stated tolerance (1e-6 mm, 1e-6°). Orientation is compared as the angle of the rotation
// between two rotation matrices, so no Euler convention or quaternion sign enters.
import { describe, expect, it } from "vitest";
import { ARMS, ARM_NAMES, type Arm, type ArmName } from "../../generated/arms";
import vectorsFile from "../../generated/armKinematicsVectors.json";
import { ArmChain, type Transform } from "./armKinematics";

type Vec3 = [number, number, number];

interface GoldenVector {
  readonly kind: string;
  readonly case: string;
  readonly joints_deg: number[];
  readonly tcp_position_mm: number[];
  readonly tcp_rotation: number[][];
  readonly joint_origins_mm: number[][];
}

interface GoldenVectors {
  readonly tolerance: { readonly position_mm: number; readonly orientation_deg: number };
  readonly arms: Readonly<Record<ArmName, readonly GoldenVector[]>>;
}

// Assigning the imported JSON checks its shape at compile time, and that it has every arm.
const golden: GoldenVectors = vectorsFile;
const { position_mm: POSITION_TOLERANCE_MM, orientation_deg: ORIENTATION_TOLERANCE_DEG } = golden.tolerance;

const DEG_PER_RAD = 180 / Math.PI;

function vec3(values: readonly number[] | undefined): Vec3 {
  if (values?.length !== 3) throw new Error(`expected 3 numbers, got ${JSON.stringify(values)}`);
  return [values[0] as number, values[1] as number, values[2] as number];
}

/** A transform's rotation (3×3, rows first) and its origin in mm. */
function rotationOf(t: Transform): number[][] {
  return [0, 1, 2].map((r) => [t[4 * r] as number, t[4 * r + 1] as number, t[4 * r + 2] as number]);
}

function originMm(t: Transform): Vec3 {
  return [(t[3] as number) * 1000, (t[7] as number) * 1000, (t[11] as number) * 1000];
}

function distance(a: Vec3, b: Vec3): number {
  return Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

/**
 * The angle (degrees) of the rotation M = Aᵀ·B that takes orientation A to B: atan2 of its sine
 * (from M's skew-symmetric part) and cosine (from its trace), which stays exact near 0°, where
 * acos of the trace alone reads one rounding (1e-16) as almost 1e-6°.
 */
function rotationAngle_deg(a: readonly number[][], b: readonly number[][]): number {
  const m = (i: number, j: number): number =>
    [0, 1, 2].reduce((sum, k) => sum + (a[k]?.[i] as number) * (b[k]?.[j] as number), 0);
  const cos = (m(0, 0) + m(1, 1) + m(2, 2) - 1) / 2;
  const sin = Math.hypot(m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1)) / 2;
  return Math.atan2(sin, cos) * DEG_PER_RAD;
}

/** How far an arm's chain is from a vector: mm for the TCP and the worst joint origin, degrees. */
function deviation(arm: Arm, vector: GoldenVector): { tcp_mm: number; joints_mm: number; orientation_deg: number } {
  const chain = new ArmChain(arm);
  const frames = chain.newFrames();
  chain.forward(vector.joints_deg, frames);
  const flange = frames[frames.length - 1] as Transform;
  if (vector.joint_origins_mm.length !== chain.jointCount) throw new Error(`${vector.case}: joint count`);
  const joints_mm = Math.max(
    ...vector.joint_origins_mm.map((origin, i) => distance(originMm(frames[i + 1] as Transform), vec3(origin))),
  );
  return {
    tcp_mm: distance(originMm(flange), vec3(vector.tcp_position_mm)),
    joints_mm,
    orientation_deg: rotationAngle_deg(rotationOf(flange), vector.tcp_rotation),
  };
}

function rotZ(angle_rad: number): number[][] {
  const c = Math.cos(angle_rad);
  const s = Math.sin(angle_rad);
  return [
    [c, -s, 0],
    [s, c, 0],
    [0, 0, 1],
  ];
}

describe("golden kinematics vectors (generated from the emulator's Python model)", () => {
  it("has vectors for every arm the 3D view knows, and for no other", () => {
    expect(Object.keys(golden.arms).sort()).toEqual([...ARM_NAMES].sort());
    for (const name of ARM_NAMES) expect(golden.arms[name].length).toBeGreaterThan(40);
  });

  for (const name of ARM_NAMES) {
    describe(name, () => {
      it.each(golden.arms[name].map((v) => [v.case, v] as const))("%s", (_case, vector) => {
        const d = deviation(ARMS[name], vector);
        expect(d.tcp_mm).toBeLessThanOrEqual(POSITION_TOLERANCE_MM);
        expect(d.joints_mm).toBeLessThanOrEqual(POSITION_TOLERANCE_MM);
        expect(d.orientation_deg).toBeLessThanOrEqual(ORIENTATION_TOLERANCE_DEG);
      });
    });
  }

  it("tells a chain that is 3 mm off from the right one (the older xacro's J6 at y = −0.124 m)", () => {
    const right = ARMS.M1013;
    const older: Arm = {
      ...right,
      joints: right.joints.map((joint, i) =>
        i === 5 ? { ...joint, originXyz_m: [0, -0.124, 0] as const } : joint,
      ),
    };
    const home = golden.arms.M1013.find((v) => v.case.startsWith("home"));
    if (home === undefined) throw new Error("no home vector");
    expect(deviation(right, home).tcp_mm).toBeLessThanOrEqual(POSITION_TOLERANCE_MM);
    expect(deviation(older, home).tcp_mm).toBeCloseTo(3, 6);
  });

  it("tells an orientation turned by a hundredth of the tolerance from the same one", () => {
    const vector = golden.arms.M1013.find((v) => v.kind === "random");
    if (vector === undefined) throw new Error("no random vector");
    const turn = rotZ((ORIENTATION_TOLERANCE_DEG / DEG_PER_RAD) * 100);
    const r = vector.tcp_rotation;
    // r·Rz(θ): the same orientation turned about the flange's z by θ.
    const turned = r.map((row) =>
      [0, 1, 2].map((j) => [0, 1, 2].reduce((sum, k) => sum + (row[k] as number) * (turn[k]?.[j] as number), 0)),
    );
    expect(rotationAngle_deg(r, r)).toBeLessThanOrEqual(ORIENTATION_TOLERANCE_DEG / 1000);
    expect(rotationAngle_deg(r, turned)).toBeCloseTo(ORIENTATION_TOLERANCE_DEG * 100, 9);
  });

  it("reads the angle between two rotations from 0° to 180°", () => {
    for (const angle_deg of [1e-9, 0.5, 90, 179.5, 180]) {
      expect(rotationAngle_deg(rotZ(0), rotZ(angle_deg / DEG_PER_RAD))).toBeCloseTo(angle_deg, 9);
    }
  });
});
