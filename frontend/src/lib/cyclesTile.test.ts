import { describe, expect, it } from "vitest";
import { CYCLE_TILE, withCycleTimes } from "./cyclesTile";
import { tileCells, tilesFromSearch } from "./kioskTiles";
import type { Frame } from "../generated/layout";

describe("the kiosk's cycle-time tile", () => {
  it("is chosen in the URL like a frame field", () => {
    const choice = tilesFromSearch("?tiles=joint_position,cycle_time");
    expect(choice.unknown).toEqual([]);
    expect(choice.fields.map((f) => f.name)).toEqual(["joint_position", "cycle_time"]);
  });

  it("shows the last cycle and the mean, a dash before the first", () => {
    const frame = { robot_state: 14 } as unknown as Frame;
    expect(tileCells(CYCLE_TILE, withCycleTimes(frame, [8.07, 8.05]))).toEqual([
      { label: "last", text: "8.1" },
      { label: "mean of 20", text: "8.1" },
    ]);
    expect(tileCells(CYCLE_TILE, withCycleTimes(frame, [null, null])).map((c) => c.text)).toEqual(["—", "—"]);
    expect(withCycleTimes(null, [1, 2])).toBeNull();
  });
});
