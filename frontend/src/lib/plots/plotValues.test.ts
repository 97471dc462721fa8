// A plot's values at the panel's cursor (lib/plots/plotValues.ts): the ring's sample nearest the time
// (none beyond the tolerance), else the recording's bucket holding it (its min and max) or the
// raw frame nearest it; the readout's text.
import { describe, expect, it } from "vitest";
import { recordingValuesAt, ringValuesAt, valueText } from "./plotValues";
import { JOINT_PLOTS, tracesOf } from "./plots";
import { SampleRing } from "../stream/ringBuffer";
import { historyAnswerOf } from "./plotTestSupport";

const T0 = 1_700_000_000_000;

describe("ringValuesAt", () => {
  const ring = new SampleRing(64, 2);
  for (let k = 0; k < 10; k++) ring.push(T0 + k * 10, [k, k === 5 ? Number.NaN : -k]);

  it("reads the sample nearest the time, per channel", () => {
    expect(ringValuesAt(ring, [0, 1], T0 + 31)).toEqual([{ value: 3 }, { value: -3 }]);
    expect(ringValuesAt(ring, [1, 0], T0 + 36)).toEqual([{ value: -4 }, { value: 4 }]);
    expect(ringValuesAt(ring, [0], T0 - 100)).toEqual([{ value: 0 }]);
    expect(ringValuesAt(ring, [0, 1], T0 + 50)).toEqual([{ value: 5 }, null]); // a missing value
  });

  it("holds nothing beyond the tolerance, before any sample or at no time", () => {
    expect(ringValuesAt(ring, [0], T0 + 90 + 251)).toBeNull();
    expect(ringValuesAt(ring, [0], T0 - 300)).toBeNull();
    expect(ringValuesAt(ring, [0], Number.NaN)).toBeNull();
    expect(ringValuesAt(new SampleRing(8, 1), [0], T0)).toBeNull();
  });
});

describe("recordingValuesAt", () => {
  const traces = tracesOf(JOINT_PLOTS[0]!);
  const answer = historyAnswerOf({ from_s: 100, to_s: 104 }); // buckets [100, 102) and [102, 104)

  it("gives the bucket holding the time, its minimum and maximum", () => {
    expect(recordingValuesAt(answer, traces, 101_500)?.[1]).toEqual({ min: 11, max: 21 });
    expect(recordingValuesAt(answer, traces, 103_000)?.[0]).toEqual({ min: 10, max: 20 });
    expect(recordingValuesAt(answer, traces, 99_000)).toBeNull();
    expect(recordingValuesAt(answer, traces, 106_500)).toBeNull();
  });

  it("gives the raw frame nearest the time, and one value where min and max agree", () => {
    const raw = historyAnswerOf({ from_s: 100, to_s: 101 }, { mode: "raw", t: [100, 100.5], bucket_s: null });
    const rawValues = { ...raw, series: raw.series.map((s, i) => ({ ...s, values: [i, i + 0.5] })) };
    expect(recordingValuesAt(rawValues, traces, 100_400)?.[2]).toEqual({ value: 2.5 });
    expect(recordingValuesAt(rawValues, traces, 100_100)?.[2]).toEqual({ value: 2 });
    const flat = { ...answer, series: answer.series.map((s) => ({ ...s, max: s.min })) };
    expect(recordingValuesAt(flat, traces, 100_000)?.[0]).toEqual({ value: 10 });
    expect(recordingValuesAt({ ...answer, series: [] }, traces, 100_000)?.[0]).toBeNull();
  });
});

describe("valueText", () => {
  it("writes four significant digits and a real minus sign; a range; a dash for none", () => {
    expect(valueText({ value: -12.3456 })).toBe("\u221212.35");
    expect(valueText({ value: 0.000123456 })).toBe("0.0001235");
    expect(valueText({ min: -1, max: 2.5 })).toBe("\u22121 … 2.5");
    expect(valueText(null)).toBe("—");
  });
});
