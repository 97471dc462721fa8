import { describe, expect, it } from "vitest";
import { tickLabel, tickStep, timeTicks } from "./timeTicks";

const at = (hms: string) => Date.parse(`2026-11-24T${hms}Z`);

describe("timeTicks", () => {
  it("puts ticks at round times inside the range, about one per 110 px", () => {
    const ticks = timeTicks(at("09:01:03.400"), at("09:01:13.400"), 540);
    // 10 s over 540 px: about 5 ticks, a 2 s step.
    expect(ticks.ticktext).toEqual(["09:01:04", "09:01:06", "09:01:08", "09:01:10", "09:01:12"]);
    expect(ticks.tickvals).toEqual([at("09:01:04"), at("09:01:06"), at("09:01:08"), at("09:01:10"), at("09:01:12")]);
  });

  it("labels minutes without seconds and tenths below a second", () => {
    expect(timeTicks(at("09:00:30"), at("09:11:00"), 540).ticktext).toEqual(["09:02", "09:04", "09:06", "09:08", "09:10"]);
    expect(tickLabel(at("09:00:01.5"), 500)).toBe("09:00:01.5");
    expect(tickStep(120_000, 5)).toBe(30_000);
    expect(tickStep(1e12, 5)).toBe(86_400_000);
  });

  it("leaves out a tick whose label the plot's right edge would cut", () => {
    // 10 s over 540 px: a label's half is about 0.6 s of the axis.
    expect(timeTicks(at("09:01:02"), at("09:01:12.3"), 540).ticktext.at(-1)).toBe("09:01:10");
    expect(timeTicks(at("09:01:02"), at("09:01:13"), 540).ticktext.at(-1)).toBe("09:01:12");
  });

  it("gives no ticks for an empty or invalid range, and at least two for a narrow plot", () => {
    expect(timeTicks(5, 5, 500).tickvals).toEqual([]);
    expect(timeTicks(Number.NaN, 5, 500).tickvals).toEqual([]);
    expect(timeTicks(at("09:00:00"), at("09:00:10"), 100).ticktext).toEqual(["09:00:00", "09:00:05"]); // a 5 s step
    expect(timeTicks(at("09:00:00"), at("09:00:10"), Number.NaN).tickvals.length).toBeGreaterThan(2);
  });
});
