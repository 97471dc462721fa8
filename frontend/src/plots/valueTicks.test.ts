// A value axis as Plotly autoranges it, for the canvas picture (plots/valueTicks.ts): 5 % padding
// each end, round steps about one per 40 px, labels with the decimals the step needs.
import { describe, expect, it } from "vitest";
import { paddedRange, valueLabel, valueStep, valueTicks } from "./valueTicks";

describe("valueTicks", () => {
  it("pads the data's range so it fills the middle 90 %; a constant ±1; nothing finite [−1, 1]", () => {
    const [a, b] = paddedRange(0, 90);
    expect(a).toBeCloseTo(-5, 9);
    expect(b).toBeCloseTo(95, 9);
    expect(paddedRange(3, 3)).toEqual([2, 4]);
    expect(paddedRange(Number.NaN, 1)).toEqual([-1, 1]);
  });

  it("steps by 1, 2 or 5 × 10ⁿ", () => {
    expect(valueStep(100, 10)).toBe(10);
    expect(valueStep(100, 6)).toBe(20);
    expect(valueStep(1, 3)).toBe(0.5);
    expect(valueStep(0, 5)).toBe(1);
  });

  it("ticks at round values within the axis, labelled with the step's decimals", () => {
    const t = valueTicks(-5, 95, 200); // 5 ticks a 200 px axis: steps of 20
    expect(t.values).toEqual([0, 20, 40, 60, 80]);
    expect(t.labels).toEqual(["0", "20", "40", "60", "80"]);
    const small = valueTicks(-0.12, 0.12, 200);
    expect(small.labels).toEqual(["\u22120.10", "\u22120.05", "0.00", "0.05", "0.10"]);
    expect(valueTicks(1, 1, 200).values).toEqual([]);
  });

  it("never writes −0", () => {
    expect(valueLabel(-1e-12, 1)).toBe("0.0");
    expect(valueLabel(-2, 0)).toBe("\u22122");
  });
});
