import { describe, expect, it } from "vitest";
import type { TrendAnswer, TrendJoint } from "./healthTypes";
import { trendRange, trendSeries } from "./trend";

function j(joint: number, friction_percent: number | null): TrendJoint {
  return { joint, verdict: "ok", friction_percent, friction_percent_since_first_baseline: null, heat_excess_c: 0.5, life_used_percent: 0.01 * joint, life_remaining_h: null, collisions_this_shift: 0, signature_rms_percent: null };
}

const ANSWER: TrendAnswer = {
  robot: "m1013",
  points: [
    { time: 200, baseline_id: 1, cycles: 20, verdict: "ok", joints: [j(1, 1.5), j(3, null)] },
    { time: 100, baseline_id: 1, cycles: 10, verdict: "ok", joints: [j(1, 1), j(3, 2)] },
    { time: 300, baseline_id: 2, cycles: 30, verdict: "watch", joints: [j(3, 9), j(1, 0.5)] },
  ],
};

describe("the health trend", () => {
  it("gives one series per joint, J1 first, in time order, with a gap where a joint had no figure", () => {
    const series = trendSeries(ANSWER, "friction_percent");
    expect(series.points).toBe(3);
    expect(series.joints.map((s) => s.joint)).toEqual([1, 3]);
    expect(series.joints[0]).toEqual({ joint: 1, x: [100_000, 200_000, 300_000], y: [1, 1.5, 0.5] });
    expect(series.joints[1]?.y).toEqual([2, null, 9]);
  });

  it("marks where a new baseline came into use", () => {
    expect(trendSeries(ANSWER, "friction_percent").baselineChanges).toEqual([{ x: 300_000, id: 2 }]);
  });

  it("shows any of its figures, and nothing without an answer", () => {
    expect(trendSeries(ANSWER, "life_used_percent").joints[1]?.y).toEqual([0.03, 0.03, 0.03]);
    expect(trendSeries(null, "heat_excess_c")).toEqual({ joints: [], baselineChanges: [], points: 0 });
  });

  it("asks for the last N days in whole seconds", () => {
    expect(trendRange(1_765_000_000_900, 7)).toEqual({ from_s: 1_765_000_000 - 7 * 86_400, to_s: 1_765_000_000 });
  });
});
