/**
 * Layer: pure wording of a joint's health figures (no React, no DOM): each figure with its unit
 * and what it is measured against, the life-used bar's fill and its words. A figure the service
 * could not compute (null) reads as why, never as 0.
 */
import type { JointHealth } from "./healthTypes";

/** One line of a joint's card: what, the value in words with its unit, and a test id. */
export interface Figure {
  readonly key: string;
  readonly label: string;
  readonly value: string;
  /** The number itself (null: none), for tests and for the CSV a person may compare with. */
  readonly raw: number | null;
}

function finite(value: number | null | undefined): number | null {
  return typeof value === "number" && Number.isFinite(value) ? value : null;
}

/** "+14.2", "−3.0", "0.0": a signed figure with one decimal (a real minus sign). */
export function signed(value: number, digits = 1): string {
  const text = Math.abs(value).toFixed(digits);
  if (Number(text) === 0) return (0).toFixed(digits);
  return `${value > 0 ? "+" : "−"}${text}`;
}

/** Whole hours with thousands grouped: "12,345 h". */
export function hoursWords(hours: number): string {
  return `${Math.round(hours).toLocaleString("en-US")} h`;
}

export function frictionWords(joint: Pick<JointHealth, "friction_percent">): string {
  const f = finite(joint.friction_percent);
  return f === null ? "not comparable with its baseline yet" : `${signed(f)} % against its baseline`;
}

export function frictionTrendWords(joint: Pick<JointHealth, "friction_percent_per_week">): string {
  const w = finite(joint.friction_percent_per_week);
  return w === null ? "not known yet (needs an hour of trend)" : `${signed(w)} % a week`;
}

export function heatWords(joint: Pick<JointHealth, "heat_excess_c">): string {
  const h = finite(joint.heat_excess_c);
  return h === null ? "not known yet" : `${signed(h)} °C for its duty`;
}

export function collisionsWords(joint: Pick<JointHealth, "collisions_this_shift">): string {
  const c = finite(joint.collisions_this_shift);
  return c === null ? "not known" : c === 0 ? "none" : String(c);
}

/** The life-used bar: its fill (0–100, capped), the used share and the remaining life in words. */
export interface LifeBar {
  readonly used_percent: number | null;
  readonly fill_percent: number;
  readonly usedWords: string;
  readonly remainingWords: string;
}

/** Life used under 0.01 % reads with enough digits to show it moving. */
function usedText(used: number): string {
  if (used === 0) return "0 %";
  if (used < 0.01) return `${used.toFixed(4)} %`;
  if (used < 1) return `${used.toFixed(2)} %`;
  return `${used.toFixed(1)} %`;
}

/** Beyond this the remaining life at this week's duty says nothing a planner uses. */
export const LONG_LIFE_H = 100 * 8766;

export function lifeBar(joint: Pick<JointHealth, "life_used_percent" | "life_remaining_h" | "life_end_date">): LifeBar {
  const used = finite(joint.life_used_percent);
  const remaining = finite(joint.life_remaining_h);
  const end = joint.life_end_date ?? null;
  let remainingWords: string;
  if (remaining === null) remainingWords = "remaining life not known (no duty measured this week)";
  else if (remaining <= 0) remainingWords = "rated life reached";
  else if (remaining > LONG_LIFE_H) remainingWords = "more than 100 years left at this week's duty";
  else remainingWords = `${hoursWords(remaining)} left at this week's duty${end !== null ? `, until ${end}` : ""}`;
  return {
    used_percent: used,
    fill_percent: used === null ? 0 : Math.min(100, Math.max(0, used)),
    usedWords: used === null ? "not known" : `${usedText(used)} used`,
    remainingWords,
  };
}

/** The rated values a joint's life and knocks are measured against, in words. */
export function ratedWords(joint: Pick<JointHealth, "rated">): string {
  const r = joint.rated;
  if (r === null || r === undefined) return "not known";
  const text = `${r.torque_nm} N·m, ${r.speed_deg_s} °/s, ${hoursWords(r.life_h)}`;
  return r.assumed ? `${text} (assumed: not published by the maker)` : text;
}

/**
 * Friction chained through every re-baselining since the first baseline, when it says more
 * than the figure against the baseline in use (after a re-baselining): null otherwise.
 */
export function frictionSinceFirstWords(joint: Pick<JointHealth, "friction_percent" | "friction_percent_since_first_baseline">): string | null {
  const since = finite(joint.friction_percent_since_first_baseline);
  const now = finite(joint.friction_percent);
  if (since === null || (now !== null && Math.abs(since - now) < 0.05)) return null;
  return `${signed(since)} % since its first baseline`;
}

/** A joint card's figures, in the order a planner reads them. */
export function jointFigures(joint: JointHealth): readonly Figure[] {
  const since = frictionSinceFirstWords(joint);
  return [
    { key: "friction", label: "friction", value: frictionWords(joint), raw: finite(joint.friction_percent) },
    ...(since !== null ? [{ key: "friction-since-first", label: "friction since the first baseline", value: since, raw: finite(joint.friction_percent_since_first_baseline) }] : []),
    { key: "friction-trend", label: "friction trend", value: frictionTrendWords(joint), raw: finite(joint.friction_percent_per_week) },
    { key: "heat", label: "heat beyond its current", value: heatWords(joint), raw: finite(joint.heat_excess_c) },
    { key: "collisions", label: "collisions this shift", value: collisionsWords(joint), raw: finite(joint.collisions_this_shift) },
    { key: "rated", label: "rated", value: ratedWords(joint), raw: null },
  ];
}
