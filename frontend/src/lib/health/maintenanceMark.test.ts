import { describe, expect, it } from "vitest";
import { joint, report, SIX_OK } from "./healthTestSupport";
import { NO_MARK, maintenanceMark } from "./maintenanceMark";

describe("the kiosk's maintenance mark", () => {
  it("shows while the service says maintenance is due, naming the joints that ask for it", () => {
    const answer = report([joint(1), joint(2), joint(3, { verdict: "act" }), joint(4), joint(5, { verdict: "watch" }), joint(6)]);
    expect(maintenanceMark(answer)).toEqual({ due: true, verdict: "act", words: "MAINTENANCE DUE: J3, J5" });
  });

  it("is not there for a healthy robot, nor before an answer", () => {
    expect(maintenanceMark(report(SIX_OK))).toEqual({ due: false, verdict: "ok", words: null });
    expect(maintenanceMark(null)).toBe(NO_MARK);
  });

  it("follows the service's maintenance_due rather than guessing from the verdicts", () => {
    expect(maintenanceMark(report([joint(1, { verdict: "watch" })], { maintenance_due: false })).due).toBe(false);
    expect(maintenanceMark(report(SIX_OK, { maintenance_due: true })).words).toBe("MAINTENANCE DUE");
  });
});
