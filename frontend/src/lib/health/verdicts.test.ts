import { describe, expect, it } from "vitest";
import { joint, SIX_OK } from "./healthTestSupport";
import { VERDICTS, isVerdict, robotVerdictWords, verdictPaint, worse, worstVerdict } from "./verdicts";

/** WCAG 2's contrast ratio of two #rrggbb colours. */
function contrast(a: string, b: string): number {
  const luminance = (hex: string) => {
    const [r, g, bl] = [1, 3, 5].map((i) => {
      const c = parseInt(hex.slice(i, i + 2), 16) / 255;
      return c <= 0.03928 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4;
    }) as [number, number, number];
    return 0.2126 * r + 0.7152 * g + 0.0722 * bl;
  };
  const [hi, lo] = [luminance(a), luminance(b)].sort((x, y) => y - x) as [number, number];
  return (hi + 0.05) / (lo + 0.05);
}

describe("verdicts", () => {
  it("orders ok < watch < act and picks the worst of a robot's joints", () => {
    expect(worse("ok", "watch")).toBe("watch");
    expect(worse("act", "watch")).toBe("act");
    expect(worse("ok", "ok")).toBe("ok");
    expect(worstVerdict(SIX_OK)).toBe("ok");
    expect(worstVerdict([joint(1), joint(3, { verdict: "watch" }), joint(5)])).toBe("watch");
    expect(worstVerdict([joint(1, { verdict: "act" }), joint(3, { verdict: "watch" })])).toBe("act");
    expect(worstVerdict([])).toBeNull();
  });

  it("names the joints of the worst verdict", () => {
    expect(robotVerdictWords(SIX_OK)).toBe("ok");
    expect(robotVerdictWords([joint(1), joint(2, { verdict: "watch" }), joint(5, { verdict: "watch" })])).toBe("watch: J2, J5");
    expect(robotVerdictWords([joint(2, { verdict: "watch" }), joint(3, { verdict: "act" })])).toBe("act: J3");
    expect(robotVerdictWords([])).toBe("no report");
  });

  it("knows a verdict from anything else", () => {
    expect(VERDICTS.every(isVerdict)).toBe(true);
    expect(isVerdict("ACT")).toBe(false);
    expect(isVerdict(null)).toBe(false);
  });

  it("paints each verdict with text readable on it (4.5:1, WCAG AA) and a colour of its own", () => {
    for (const v of VERDICTS) expect(contrast(verdictPaint(v).background, verdictPaint(v).text)).toBeGreaterThanOrEqual(4.5);
    expect(new Set(VERDICTS.map((v) => verdictPaint(v).background)).size).toBe(3);
  });
});
