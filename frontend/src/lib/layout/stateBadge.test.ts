import { describe, expect, it } from "vitest";
import { LAYOUT, UNKNOWN_STATE_NAME } from "../../generated/layout";
import { NO_DATA_LABEL, NO_DATA_NAME, UNKNOWN_LABEL, UNKNOWN_PAINT, paintOf, stateBadge, stateTooltip } from "./stateBadge";

describe("stateBadge", () => {
  it("knows all 21 states of the layout", () => {
    expect(LAYOUT.robot_states).toHaveLength(21);
    const values = LAYOUT.robot_states.map((s) => s.value);
    expect(new Set(values).size).toBe(21);
  });

  it.each(LAYOUT.robot_states.map((s) => [s.value, s] as const))(
    "state %i: name, description, pendant colours from the layout",
    (value, info) => {
      const badge = stateBadge(value);
      expect(badge.known).toBe(true);
      expect(badge.name).toBe(info.name);
      expect(badge.label).toBe(info.label);
      expect(badge.label).not.toBe(info.name);
      expect(stateTooltip(badge)).toBe(`${info.description} (${info.name})`);
      expect(badge.description).toBe(info.description);
      expect(badge.colours).toEqual(info.pendant_colours);
      expect(badge.alternating).toBe(info.pendant_colours.length > 1);
      expect(badge.paints).toHaveLength(info.pendant_colours.length);
      for (const p of badge.paints) expect(p).not.toBe(UNKNOWN_PAINT);
    },
  );

  it("uses the teach-pendant semantics of the issue", () => {
    const byName = (name: string) => {
      const info = LAYOUT.robot_states.find((s) => s.name === name);
      if (info === undefined) throw new Error(name);
      return stateBadge(info.value);
    };
    expect(byName("STANDALONE_RUNNING").colours).toEqual(["white"]);
    expect(byName("STANDALONE_RUNNING").label).toBe("Standalone running");
    expect(byName("INTERRUPTED").label).toBe("Protective stop");
    expect(byName("COLLABORATIVE_RUNNING").colours).toEqual(["green"]);
    expect(byName("EMERGENCY_STOP").colours).toEqual(["red"]);
    const hp = byName("HIGH_PRIORITY_RUNNING");
    expect(hp.colours).toEqual(["white", "yellow"]);
    expect(hp.alternating).toBe(true);
    expect(hp.paints[0]).toEqual(paintOf("white"));
    expect(hp.paints[1]).toEqual(paintOf("yellow"));
    expect(paintOf("red").background).not.toBe(paintOf("white").background);
  });

  it("shows an unknown value as UNKNOWN with a neutral paint and says which value", () => {
    const badge = stateBadge(42);
    expect(badge.known).toBe(false);
    expect(badge.name).toBe(UNKNOWN_STATE_NAME);
    expect(badge.label).toBe(UNKNOWN_LABEL);
    expect(badge.description).toContain("42");
    expect(badge.paints).toEqual([UNKNOWN_PAINT]);
    expect(badge.alternating).toBe(false);
  });

  it("shows NO DATA before the first frame", () => {
    expect(stateBadge(null).name).toBe(NO_DATA_NAME);
    expect(stateBadge(null).label).toBe(NO_DATA_LABEL);
    expect(stateBadge(undefined).known).toBe(false);
  });
});
