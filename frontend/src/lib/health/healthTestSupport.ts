// Health answers as the service sends them (docs/health.md "The report"), for the tests of lib/health/.
import type { BaselineRecord, HealthAnswer, JointHealth } from "./healthTypes";

export function joint(n: number, over: Partial<JointHealth> = {}): JointHealth {
  return {
    joint: n,
    verdict: "ok",
    reason: `J${n}: friction +0.4 % against its baseline of 1 Dec, 0.01 % of rated life used`,
    friction_percent: 0.4,
    friction_percent_per_week: null,
    friction_percent_since_first_baseline: 0.4,
    friction_reference: "steady",
    signature_rms_percent: 1.2,
    signature_distribution_percent: 0.8,
    heat_excess_c: 0.3,
    life_used_percent: 0.0123,
    life_remaining_h: 19_876,
    life_end_date: "2029-04-30",
    collisions_this_shift: 0,
    rated: { torque_nm: 346, speed_deg_s: 120, life_h: 20_000, assumed: true },
    ...over,
  };
}

export function baseline(id: number, over: Partial<BaselineRecord> = {}): BaselineRecord {
  return {
    id,
    active: false,
    arm: "M1013",
    created_at: 1_764_000_000 + id * 1000,
    created_by: "alice",
    cycles: 50,
    layout_version: 3,
    learned_from: 1_764_000_000 + id * 1000,
    learned_to: 1_764_000_500 + id * 1000,
    learning: false,
    reason: `baseline ${id}`,
    target_cycles: 50,
    ...over,
  };
}

export function report(joints: readonly JointHealth[], over: Partial<HealthAnswer> = {}): HealthAnswer {
  const worst = joints.some((j) => j.verdict === "act") ? "act" : joints.some((j) => j.verdict === "watch") ? "watch" : "ok";
  return {
    robot: "m1013",
    arm: "M1013",
    time: 1_765_000_000,
    cycles: 120,
    dropped_frames: 0,
    baseline: baseline(1, { active: true }),
    learning: null,
    joints: [...joints],
    cycle_time: { verdict: "ok", reason: "cycle time as in its baseline (6.20 s)", baseline_s: 6.2 },
    knocks: { shift_start: 1_764_993_600, collisions: [0, 0, 0, 0, 0, 0], protective_stop: 0, emergency_stop: 0, servo_off: 0, events: [] },
    maintenance_due: worst !== "ok",
    verdict: worst,
    ...over,
  };
}

export const SIX_OK: readonly JointHealth[] = [1, 2, 3, 4, 5, 6].map((n) => joint(n));
