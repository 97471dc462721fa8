/**
 * Layer: pure rules of the health verdicts (no React, no DOM): their order, the worst of a
 * robot's joints, their words and their paint. A verdict is always shown in words beside its
 * colour (a colour alone says nothing to a colour-blind planner, nor on a black-and-white print).
 */
import type { Paint } from "../layout/stateBadge";
import type { JointHealth, Verdict } from "./healthTypes";

/** Every verdict, least urgent first. */
export const VERDICTS = ["ok", "watch", "act"] as const satisfies readonly Verdict[];

const RANK: Readonly<Record<Verdict, number>> = { ok: 0, watch: 1, act: 2 };

export function isVerdict(value: unknown): value is Verdict {
  return value === "ok" || value === "watch" || value === "act";
}

/** The more urgent of two verdicts. */
export function worse(a: Verdict, b: Verdict): Verdict {
  return RANK[a] >= RANK[b] ? a : b;
}

/** The worst verdict of a robot's joints (null: no joint reported). */
export function worstVerdict(joints: readonly Pick<JointHealth, "verdict">[]): Verdict | null {
  let worst: Verdict | null = null;
  for (const joint of joints) worst = worst === null ? joint.verdict : worse(worst, joint.verdict);
  return worst;
}

/** The verdict in words, for a card's heading and a tile: what it asks of a person. */
export const VERDICT_WORDS: Readonly<Record<Verdict, string>> = {
  ok: "ok",
  watch: "watch",
  act: "act",
};

/** What the verdict asks of a maintenance planner, in a sentence's end. */
export const VERDICT_MEANING: Readonly<Record<Verdict, string>> = {
  ok: "nothing to do",
  watch: "keep an eye on it, plan a look",
  act: "plan maintenance now",
};

/**
 * Paint with 4.5:1 contrast for small text (WCAG 1.4.3): green, amber and red as a light
 * tower's, darker than the pendant's so white or black text reads on them.
 */
const PAINT: Readonly<Record<Verdict, Paint>> = {
  ok: { background: "#157f3b", text: "#ffffff" },
  watch: { background: "#f5c400", text: "#111111" },
  act: { background: "#b71c1c", text: "#ffffff" },
};

export function verdictPaint(verdict: Verdict): Paint {
  return PAINT[verdict];
}

/** The robot's verdict in words for a tile ("act: J3", "watch: J2, J5", "ok"). */
export function robotVerdictWords(joints: readonly Pick<JointHealth, "joint" | "verdict">[]): string {
  const worst = worstVerdict(joints);
  if (worst === null) return "no report";
  if (worst === "ok") return "ok";
  const named = joints.filter((j) => j.verdict === worst).map((j) => `J${j.joint}`);
  return `${worst}: ${named.join(", ")}`;
}
