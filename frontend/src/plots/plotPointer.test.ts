// Where the pointer and the keys put a plot's time axis (plots/plotPointer.ts, plots/plotKeys.ts):
// the time under a pixel, the wheel's zoom factor, the cursor's key steps, the keys' actions.
import { describe, expect, it } from "vitest";
import { plotKeyAction } from "./plotKeys";
import { CURSOR_KEY_SHARE, WHEEL_NOTCH_FACTOR, cursorAfterKey, shareOfRange, timeAtPixel, wheelFactor } from "./plotPointer";

const margin = { l: 64, r: 16, t: 8, b: 36 };
const range = { from: 10_000, to: 20_000 };

describe("timeAtPixel", () => {
  it("maps the plotting area (inside the margins) onto the range", () => {
    expect(timeAtPixel(64, 880, margin, range)).toBe(10_000);
    expect(timeAtPixel(864, 880, margin, range)).toBe(20_000);
    expect(timeAtPixel(464, 880, margin, range)).toBe(15_000);
  });

  it("is null in the margins, without a range or an area", () => {
    expect(timeAtPixel(20, 880, margin, range)).toBeNull();
    expect(timeAtPixel(870, 880, margin, range)).toBeNull();
    expect(timeAtPixel(464, 880, margin, null)).toBeNull();
    expect(timeAtPixel(464, 880, margin, { from: 5, to: 5 })).toBeNull();
    expect(timeAtPixel(70, 60, margin, range)).toBeNull();
  });

  it("and back: where a time is across the range", () => {
    expect(shareOfRange(15_000, range)).toBe(0.5);
    expect(shareOfRange(9_000, range)).toBeNull();
    expect(shareOfRange(15_000, null)).toBeNull();
  });
});

describe("wheelFactor", () => {
  it("zooms out a notch turning down, in turning up, whatever the delta's unit", () => {
    expect(wheelFactor(100)).toBeCloseTo(WHEEL_NOTCH_FACTOR, 9);
    expect(wheelFactor(-100)).toBeCloseTo(1 / WHEEL_NOTCH_FACTOR, 9);
    expect(wheelFactor(3, 1)).toBeCloseTo(WHEEL_NOTCH_FACTOR, 9); // three lines
    expect(wheelFactor(10)).toBeGreaterThan(1); // a touchpad's small step: a little
    expect(wheelFactor(10)).toBeLessThan(1.05);
  });

  it("at most four notches at once; no turn, no zoom", () => {
    expect(wheelFactor(5000)).toBeCloseTo(WHEEL_NOTCH_FACTOR ** 4, 9);
    expect(wheelFactor(1, 2)).toBeCloseTo(WHEEL_NOTCH_FACTOR ** 4, 9);
    expect(wheelFactor(0)).toBe(1);
    expect(wheelFactor(Number.NaN)).toBe(1);
  });
});

describe("the cursor by key", () => {
  it("starts in the middle of the range, then steps within it", () => {
    expect(cursorAfterKey(null, 1, range)).toBe(15_000);
    expect(cursorAfterKey(15_000, 1, range)).toBe(15_000 + 10_000 * CURSOR_KEY_SHARE);
    expect(cursorAfterKey(15_000, -1, range)).toBe(15_000 - 10_000 * CURSOR_KEY_SHARE);
    expect(cursorAfterKey(19_990, 1, range)).toBe(20_000);
    expect(cursorAfterKey(5_000, -1, range)).toBe(15_000); // left behind by the range: the middle again
    expect(cursorAfterKey(15_000, 1, null)).toBeNull();
  });

  it("Shift + ← / → move the cursor; ← / → step the axis; + and − zoom", () => {
    expect(plotKeyAction("ArrowLeft", true)).toEqual({ cursor: -1 });
    expect(plotKeyAction("ArrowRight", true)).toEqual({ cursor: 1 });
    expect(plotKeyAction("ArrowLeft", false)).toEqual({ step: "earlier" });
    expect(plotKeyAction("ArrowRight", false)).toEqual({ step: "later" });
    expect(plotKeyAction("+", true)).toEqual({ step: "zoomIn" });
    expect(plotKeyAction("-", false)).toEqual({ step: "zoomOut" });
    expect(plotKeyAction("a", false)).toBeNull();
  });
});
