import { describe, expect, it } from "vitest";
import { defaultShelveChoice, SHELVE_CHOICES_S, shelveChoices, shelveRefusal } from "./alarms";

describe("the shelving an alarm allows (ISA-18.2: a maximum per priority, never the safety stops)", () => {
  it("offers only the durations within the alarm's maximum", () => {
    const high = shelveChoices({ shelve_max_s: 3600 });
    expect(high.map(([, words]) => words)).toEqual(["15 min", "1 h"]);
    expect(defaultShelveChoice(high)).toBe(3600);
    const medium = shelveChoices({ shelve_max_s: 4 * 3600 });
    expect(medium.map(([s]) => s)).toEqual([900, 3600, 14_400]);
    expect(shelveChoices({ shelve_max_s: 8 * 3600 })).toEqual(SHELVE_CHOICES_S);
  });

  it("offers the maximum alone when it is shorter than every choice", () => {
    const short = shelveChoices({ shelve_max_s: 600 });
    expect(short).toEqual([[600, "10 min"]]);
    expect(defaultShelveChoice(short)).toBe(600);
    expect(shelveChoices({ shelve_max_s: 90 })).toEqual([[90, "90 s"]]);
  });

  it("offers nothing for an alarm that is never shelved, and says why", () => {
    const estop = { shelve_max_s: null, shelve_refusal: "Emergency stop is a safety stop: it cannot be shelved" };
    expect(shelveChoices(estop)).toEqual([]);
    expect(defaultShelveChoice([])).toBeNull();
    expect(shelveRefusal(estop)).toBe("Emergency stop is a safety stop: it cannot be shelved");
    expect(shelveRefusal({ shelve_max_s: null })).toBe("this alarm cannot be shelved");
    expect(shelveRefusal({ shelve_max_s: 3600, shelve_refusal: null })).toBeNull();
  });

  it("leaves the choice to a service that does not say (it refuses what it does not allow)", () => {
    expect(shelveChoices({})).toEqual(SHELVE_CHOICES_S);
    expect(shelveRefusal({})).toBeNull();
  });
});
