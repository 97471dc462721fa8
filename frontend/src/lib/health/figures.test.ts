import { describe, expect, it } from "vitest";
import { collisionsWords, frictionSinceFirstWords, frictionTrendWords, frictionWords, heatWords, hoursWords, jointFigures, lifeBar, ratedWords, signed } from "./figures";
import { joint } from "./healthTestSupport";

describe("a joint's figures in words", () => {
  it("signs a figure with one decimal and a real minus sign, never '−0.0'", () => {
    expect(signed(14.23)).toBe("+14.2");
    expect(signed(-3)).toBe("−3.0");
    expect(signed(-0.04)).toBe("0.0");
    expect(signed(2.5, 0)).toBe("+3");
  });

  it("says each figure with its unit and what it is measured against, and why when there is none", () => {
    expect(frictionWords({ friction_percent: 14.2 })).toBe("+14.2 % against its baseline");
    expect(frictionWords({ friction_percent: null })).toBe("not comparable with its baseline yet");
    expect(frictionTrendWords({ friction_percent_per_week: 2 })).toBe("+2.0 % a week");
    expect(frictionTrendWords({ friction_percent_per_week: null })).toMatch(/^not known yet/);
    expect(heatWords({ heat_excess_c: 6.04 })).toBe("+6.0 °C for its duty");
    expect(heatWords({ heat_excess_c: null })).toBe("not known yet");
    expect(collisionsWords({ collisions_this_shift: 0 })).toBe("none");
    expect(collisionsWords({ collisions_this_shift: 3 })).toBe("3");
    expect(hoursWords(19875.6)).toBe("19,876 h");
  });

  it("fills the life bar with the life used, capped at 100 %, and says the life left in hours and as a date", () => {
    expect(lifeBar({ life_used_percent: 12.34, life_remaining_h: 17_532, life_end_date: "2028-12-01" })).toEqual({
      used_percent: 12.34,
      fill_percent: 12.34,
      usedWords: "12.3 % used",
      remainingWords: "17,532 h left at this week's duty, until 2028-12-01",
    });
    expect(lifeBar({ life_used_percent: 130, life_remaining_h: 0, life_end_date: null })).toMatchObject({ fill_percent: 100, remainingWords: "rated life reached" });
    expect(lifeBar({ life_used_percent: 0.0012, life_remaining_h: null, life_end_date: null })).toMatchObject({
      usedWords: "0.0012 % used",
      remainingWords: "remaining life not known (no duty measured this week)",
    });
    expect(lifeBar({ life_used_percent: 0.5, life_remaining_h: 10, life_end_date: null }).usedWords).toBe("0.50 % used");
    // A robot that barely moved this week: no date thousands of years away.
    expect(lifeBar({ life_used_percent: 0, life_remaining_h: 3_092_489_506, life_end_date: "354816-06-17" }).remainingWords).toBe("more than 100 years left at this week's duty");
  });

  it("says where a rated value is an assumption", () => {
    expect(ratedWords({ rated: { torque_nm: 346, speed_deg_s: 120, life_h: 20_000, assumed: true } })).toBe("346 N·m, 120 °/s, 20,000 h (assumed: not published by the maker)");
    expect(ratedWords({ rated: { torque_nm: 50, speed_deg_s: 225, life_h: 6000, assumed: false } })).toBe("50 N·m, 225 °/s, 6,000 h");
  });

  it("chains friction through re-baselinings only where that says more than the baseline in use", () => {
    expect(frictionSinceFirstWords({ friction_percent: 2, friction_percent_since_first_baseline: 16.04 })).toBe("+16.0 % since its first baseline");
    expect(frictionSinceFirstWords({ friction_percent: 2, friction_percent_since_first_baseline: 2 })).toBeNull();
    expect(frictionSinceFirstWords({ friction_percent: null, friction_percent_since_first_baseline: null })).toBeNull();
    const keys = jointFigures(joint(2, { friction_percent: 1, friction_percent_since_first_baseline: 9 })).map((f) => f.key);
    expect(keys.slice(0, 2)).toEqual(["friction", "friction-since-first"]);
  });

  it("lists a card's figures in the order a planner reads them, each with its number", () => {
    const figures = jointFigures(joint(3, { friction_percent: 25.3, friction_percent_since_first_baseline: 25.3, collisions_this_shift: 2 }));
    expect(figures.map((f) => f.key)).toEqual(["friction", "friction-trend", "heat", "collisions", "rated"]);
    expect(figures[0]).toMatchObject({ value: "+25.3 % against its baseline", raw: 25.3 });
    expect(figures[3]).toMatchObject({ value: "2", raw: 2 });
  });
});
