import { describe, expect, it } from "vitest";
import { burnInOffset } from "./burnIn";

describe("burnInOffset", () => {
  it("moves every period and stays within the amplitude", () => {
    const seen = new Set<string>();
    for (let step = 0; step < 100; step++) {
      const o = burnInOffset(step * 60_000 + 123, 60_000, 6);
      expect(Math.abs(o.dx_px)).toBeLessThanOrEqual(6);
      expect(Math.abs(o.dy_px)).toBeLessThanOrEqual(6);
      seen.add(`${o.dx_px},${o.dy_px}`);
    }
    expect(seen.size).toBeGreaterThan(4);
  });
  it("holds still within one period", () => {
    expect(burnInOffset(60_001, 60_000, 6)).toEqual(burnInOffset(119_999, 60_000, 6));
    expect(burnInOffset(60_001, 60_000, 6)).not.toEqual(burnInOffset(120_000, 60_000, 6));
  });
});
