// The steps of a plot's time axis from its buttons, keys and the mouse wheel (lib/plots/plotSteps.ts): zoom ×½ / ×2
// around the centre, pan by half the span, "Later" onto now is live, spans within limits.
import { describe, expect, it } from "vitest";
import { MAX_STEP_SPAN_MS, MIN_STEP_SPAN_MS, stepRange, zoomAround } from "./plotSteps";

const NOW = 1_795_500_000_000;

describe("stepRange", () => {
  const past = { from: NOW - 100_000, to: NOW - 60_000 }; // 40 s, ending 60 s ago

  it("zooms in to half the span around the centre", () => {
    expect(stepRange(past, "zoomIn", NOW)).toEqual({ from: NOW - 90_000, to: NOW - 70_000 });
  });

  it("zooms out to twice the span around the centre", () => {
    expect(stepRange(past, "zoomOut", NOW)).toEqual({ from: NOW - 120_000, to: NOW - 40_000 });
  });

  it("a zoom out never reaches past now: the doubled span ends at now", () => {
    const live = { from: NOW - 10_000, to: NOW };
    expect(stepRange(live, "zoomOut", NOW)).toEqual({ from: NOW - 20_000, to: NOW });
    const near = { from: NOW - 30_000, to: NOW - 10_000 };
    expect(stepRange(near, "zoomOut", NOW)).toEqual({ from: NOW - 40_000, to: NOW });
  });

  it("pans by half the span, earlier and later", () => {
    expect(stepRange(past, "earlier", NOW)).toEqual({ from: NOW - 120_000, to: NOW - 80_000 });
    expect(stepRange(past, "later", NOW)).toEqual({ from: NOW - 80_000, to: NOW - 40_000 });
  });

  it("later onto now, or from a range at now, is live", () => {
    expect(stepRange({ from: NOW - 30_000, to: NOW - 10_000 }, "later", NOW)).toBe("live");
    expect(stepRange({ from: NOW - 40_000, to: NOW - 20_000 }, "later", NOW)).toEqual({ from: NOW - 30_000, to: NOW - 10_000 });
    expect(stepRange({ from: NOW - 10_000, to: NOW }, "later", NOW)).toBe("live");
    // Frames keep coming between steps: within a tenth of the span of now is at now.
    expect(stepRange({ from: NOW - 10_000, to: NOW - 900 }, "later", NOW)).toBe("live");
    expect(stepRange({ from: NOW - 15_500, to: NOW - 5500 }, "later", NOW)).toBe("live"); // onto now - 0.5 s
    expect(stepRange({ from: NOW - 22_000, to: NOW - 12_000 }, "later", NOW)).toEqual({ from: NOW - 17_000, to: NOW - 7000 });
  });

  it("keeps the span within its limits; a step at a limit changes nothing", () => {
    expect(stepRange({ from: NOW - 61_500, to: NOW - 60_000 }, "zoomIn", NOW)).toEqual({
      from: NOW - 60_750 - MIN_STEP_SPAN_MS / 2,
      to: NOW - 60_750 + MIN_STEP_SPAN_MS / 2,
    });
    expect(stepRange({ from: NOW - 61_000, to: NOW - 60_000 }, "zoomIn", NOW)).toBeNull();
    const week = { from: NOW - MAX_STEP_SPAN_MS, to: NOW };
    expect(stepRange(week, "zoomOut", NOW)).toBeNull();
    const fiveDays = { from: NOW - 5 * 86_400_000, to: NOW };
    expect(stepRange(fiveDays, "zoomOut", NOW)).toEqual(week);
  });

  it("no range, no step", () => {
    expect(stepRange({ from: NOW, to: NOW }, "zoomOut", NOW)).toBeNull();
    expect(stepRange({ from: NOW, to: NOW - 1 }, "earlier", NOW)).toBeNull();
    expect(stepRange({ from: Number.NaN, to: NOW }, "zoomIn", NOW)).toBeNull();
  });
});

describe("zoomAround (the mouse wheel)", () => {
  const past = { from: NOW - 100_000, to: NOW - 60_000 }; // 40 s, ending 60 s ago

  it("keeps the time under the pointer where it is", () => {
    // The pointer a quarter in: 10 s after the start; zoomed in to 20 s, it is 5 s after it.
    expect(zoomAround(past, NOW - 90_000, 0.5, NOW)).toEqual({ from: NOW - 95_000, to: NOW - 75_000 });
    expect(zoomAround(past, NOW - 90_000, 2, NOW)).toEqual({ from: NOW - 110_000, to: NOW - 30_000 });
  });

  it("never past now, and within the span's limits", () => {
    const live = { from: NOW - 10_000, to: NOW };
    expect(zoomAround(live, NOW - 1000, 4, NOW)).toEqual({ from: NOW - 40_000, to: NOW });
    expect(zoomAround({ from: NOW - 2000, to: NOW }, NOW - 1000, 0.1, NOW)).toEqual({ from: NOW - 1500, to: NOW - 500 });
    expect(zoomAround({ from: NOW - MIN_STEP_SPAN_MS, to: NOW }, NOW, 0.5, NOW)).toBeNull();
    expect(zoomAround({ from: NOW - MAX_STEP_SPAN_MS, to: NOW }, NOW, 2, NOW)).toBeNull();
  });

  it("a pointer outside the range counts as its nearer end; no range, no factor: nothing", () => {
    expect(zoomAround(past, NOW, 0.5, NOW)).toEqual({ from: NOW - 80_000, to: NOW - 60_000 });
    expect(zoomAround({ from: NOW, to: NOW }, NOW, 0.5, NOW)).toBeNull();
    expect(zoomAround(past, Number.NaN, 0.5, NOW)).toBeNull();
    expect(zoomAround(past, NOW, 0, NOW)).toBeNull();
  });
});
