import { describe, expect, it } from "vitest";
import { cycleFigures, cyclesCsvUrl, formatCycle_s, histogram, interruptedWords, splitCycles, type CycleRow } from "./cycles";

describe("cycle timing's figures", () => {
  it("bins durations from their minimum to their maximum, the maximum in the last bin", () => {
    const h = histogram([1, 2, 2, 3, 5], 4);
    expect(h.width_s).toBe(1);
    expect(h.counts).toEqual([1, 2, 1, 1]);
    expect(h.centres_s).toEqual([1.5, 2.5, 3.5, 4.5]);
    expect(h.counts.reduce((a, b) => a + b, 0)).toBe(5);
  });

  it("puts equal durations in one narrow bin and leaves none for no cycles", () => {
    expect(histogram([8.07, 8.07])).toEqual({ centres_s: [8.07], counts: [2], width_s: 0.1 });
    expect(histogram([])).toEqual({ centres_s: [], counts: [], width_s: 0 });
    expect(histogram([Number.NaN, 4]).counts).toEqual([1]);
  });

  it("says durations in seconds, a dash when there is none", () => {
    expect(formatCycle_s(8.0712)).toBe("8.07 s");
    expect(formatCycle_s(null)).toBe("—");
    expect(
      cycleFigures({ count: 3, interrupted: 0, include_interrupted: false, last_s: 8.1, window: 3, mean_s: 8.05, min_s: 8, max_s: 8.1 }),
    ).toEqual({ last: "8.10 s", mean: "8.05 s" });
  });

  it("links the CSV of every cycle of the robot", () => {
    expect(cyclesCsvUrl("cell-1")).toBe("/api/v1/robots/cell-1/cycles?format=csv&limit=100000");
  });

  it("keeps interrupted cycles apart from the trend and the histogram (issue 38)", () => {
    const row = (id: number, duration_s: number, interruption: string | null = null): CycleRow => ({
      id,
      start: id * 10,
      end: id * 10 + duration_s,
      duration_s,
      interrupted: interruption !== null,
      interruption,
    });
    const cycles = [...Array.from({ length: 61 }, (_, i) => row(i, 8.07)), row(61, 142, "Emergency stop"), row(62, 8.1)];
    const { drawn, interrupted } = splitCycles(cycles);
    expect(drawn).toHaveLength(62);
    expect(interrupted.map((c) => c.interruption)).toEqual(["Emergency stop"]);
    // 61 cycles of 8.07 s are no longer one bar beside a 142 s one.
    expect(histogram(drawn.map((c) => c.duration_s)).width_s).toBeLessThan(0.01);
    expect(splitCycles(cycles, true).drawn).toHaveLength(63);
    const stats = { count: 62, interrupted: 1, include_interrupted: false, last_s: 8.1, window: 20, mean_s: 8.07, min_s: 8.07, max_s: 8.1 };
    expect(interruptedWords(stats)).toBe("1 interrupted cycle, left out of the statistics");
    expect(interruptedWords({ ...stats, interrupted: 2, include_interrupted: true })).toBe("2 interrupted cycles, included in the statistics");
    expect(interruptedWords({ ...stats, interrupted: 0 })).toBe("");
  });
});
