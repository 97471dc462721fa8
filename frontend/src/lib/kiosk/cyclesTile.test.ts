import { describe, expect, it } from "vitest";
import { CYCLE_TILE, isSlowCycle, shiftStart_ms, withCycleTimes } from "./cyclesTile";
import { tileCells, tilesFromSearch } from "./kioskTiles";
import type { Frame } from "../../generated/layout";

describe("the kiosk's cycle tile", () => {
  it("is chosen in the URL like a frame field", () => {
    const choice = tilesFromSearch("?tiles=joint_position,cycle_time");
    expect(choice.unknown).toEqual([]);
    expect(choice.fields.map((f) => f.name)).toEqual(["joint_position", "cycle_time"]);
  });

  it("shows the last cycle, the mean of the last ten and the shift's count, a dash before the first", () => {
    const frame = { robot_state: 14 } as unknown as Frame;
    expect(tileCells(CYCLE_TILE, withCycleTimes(frame, { last_s: 8.07, mean_s: 8.05, shiftCount: 112 }))).toEqual([
      { label: "last", text: "8.1" },
      { label: "mean of 10", text: "8.1" },
      { label: "this shift", text: "112" },
    ]);
    expect(tileCells(CYCLE_TILE, withCycleTimes(frame, { last_s: null, mean_s: null, shiftCount: null })).map((c) => c.text)).toEqual(["—", "—", "—"]);
    expect(withCycleTimes(null, { last_s: 1, mean_s: 2, shiftCount: 0 })).toBeNull();
  });

  it("marks the last cycle slow when it took over a tenth more than the mean of the last ten", () => {
    const frame = { robot_state: 14 } as unknown as Frame;
    expect(isSlowCycle({ last_s: 9.0, mean_s: 8.0, shiftCount: 3 })).toBe(true);
    expect(isSlowCycle({ last_s: 8.7, mean_s: 8.0, shiftCount: 3 })).toBe(false);
    expect(isSlowCycle({ last_s: 9.0, mean_s: null, shiftCount: 3 })).toBe(false);
    expect(tileCells(CYCLE_TILE, withCycleTimes(frame, { last_s: 9.0, mean_s: 8.0, shiftCount: 3 }))[0]).toEqual({ label: "last", text: "9.0", slow: true });
    expect(tileCells(CYCLE_TILE, withCycleTimes(frame, { last_s: 8.0, mean_s: 8.0, shiftCount: 3 }))[0]?.slow).toBeUndefined();
  });

  it("counts from the start of the shift in progress, in the plant's zone, across midnight", () => {
    const starts = ["06:00", "14:00", "22:00"];
    // 10:30 in Berlin (summer, UTC+2) is 08:30 UTC: the 06:00 shift, which began at 04:00 UTC.
    expect(shiftStart_ms(Date.UTC(2026, 6, 1, 8, 30), starts, "Europe/Berlin")).toBe(Date.UTC(2026, 6, 1, 4, 0));
    // 02:00 UTC is 04:00 in Berlin: the night shift of the day before (22:00 = 20:00 UTC).
    expect(shiftStart_ms(Date.UTC(2026, 6, 1, 2, 0), starts, "Europe/Berlin")).toBe(Date.UTC(2026, 5, 30, 20, 0));
    // Exactly at a start: that shift.
    expect(shiftStart_ms(Date.UTC(2026, 0, 5, 14, 0), starts, "UTC")).toBe(Date.UTC(2026, 0, 5, 14, 0));
    // One shift a day.
    expect(shiftStart_ms(Date.UTC(2026, 0, 5, 5, 0), ["07:30"], "UTC")).toBe(Date.UTC(2026, 0, 4, 7, 30));
  });
});
