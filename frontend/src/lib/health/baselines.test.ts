import { describe, expect, it } from "vitest";
import { baselineBlockedReason, baselineRefusalWords, baselineRows, checkBaselineForm, checkPeriodBaselineForm } from "./baselines";
import { baseline } from "./healthTestSupport";

describe("the re-baselining form", () => {
  it("needs a reason and a whole number of cycles, and sends them trimmed", () => {
    expect(checkBaselineForm("  J3 reducer replaced ", "30")).toEqual({ ok: true, body: { reason: "J3 reducer replaced", cycles: 30 } });
    expect(checkBaselineForm("   ", "30")).toMatchObject({ ok: false, field: "reason" });
    expect(checkBaselineForm("new program", "")).toMatchObject({ ok: false, field: "cycles" });
    expect(checkBaselineForm("new program", "2.5")).toMatchObject({ ok: false, field: "cycles" });
    expect(checkBaselineForm("new program", "0")).toMatchObject({ ok: false, field: "cycles", reason: "between 1 and 100,000 cycles" });
  });

  it("or a recorded period: both ends, the end after the start, at most 7 days, sent as typed", () => {
    expect(checkPeriodBaselineForm(" new program ", "2026-12-01T06:00", "2026-12-01T14:00")).toEqual({ ok: true, body: { reason: "new program", from: "2026-12-01T06:00", to: "2026-12-01T14:00" } });
    expect(checkPeriodBaselineForm("", "2026-12-01T06:00", "2026-12-01T14:00")).toMatchObject({ ok: false, field: "reason" });
    expect(checkPeriodBaselineForm("r", "", "2026-12-01T14:00")).toMatchObject({ ok: false, field: "from" });
    expect(checkPeriodBaselineForm("r", "2026-12-01T06:00", "")).toMatchObject({ ok: false, field: "to" });
    expect(checkPeriodBaselineForm("r", "2026-12-01T14:00", "2026-12-01T06:00")).toMatchObject({ ok: false, field: "to", reason: "the period must end after it starts" });
    expect(checkPeriodBaselineForm("r", "2026-12-01T06:00", "2026-12-09T06:00")).toMatchObject({ ok: false, field: "to", reason: "a period of at most 7 days" });
  });

  it("is offered to operators and admins only, saying why to anyone else", () => {
    expect(baselineBlockedReason(null)).toBe("Log in as an operator to set a new baseline.");
    expect(baselineBlockedReason({ name: "vic", role: "viewer" })).toBe("Setting a baseline needs an operator; vic is a viewer.");
    expect(baselineBlockedReason({ name: "op", role: "operator" })).toBeNull();
    expect(baselineBlockedReason({ name: "ad", role: "admin" })).toBeNull();
  });

  it("says the service's refusal in words a person acts on", () => {
    expect(baselineRefusalWords(403, "operator role required")).toBe("Refused: setting a baseline needs an operator (operator role required).");
    expect(baselineRefusalWords(409, "a baseline is being learned")).toBe("Refused: a baseline is being learned");
    expect(baselineRefusalWords(422, "reason: required")).toBe("Refused, the form is not right: reason: required");
    expect(baselineRefusalWords(401, "login required")).toMatch(/^Not logged in any more/);
    expect(baselineRefusalWords(503, "audit trail cannot be written")).toBe("The service did not set the baseline: audit trail cannot be written");
  });
});

describe("the baselines' list", () => {
  it("lists the one being learned first, then the others newest first, the one in use marked, with who set each and why", () => {
    const rows = baselineRows(
      [baseline(1), baseline(2, { active: true, created_by: "bob", reason: "J3 reducer replaced" }), baseline(3, { learning: true, learned_to: null, cycles: 4, target_cycles: 20 })],
      "UTC",
    );
    expect(rows.map((r) => [r.id, r.inUse, r.learning])).toEqual([
      [3, false, true],
      [2, true, false],
      [1, false, false],
    ]);
    expect(rows[0]).toMatchObject({ finished: "learning…", learnedFrom: "4 of 20 cycles so far" });
    expect(rows[1]).toMatchObject({ by: "bob", reason: "J3 reducer replaced", learnedFrom: "50 cycles", started: "2025-11-24 16:33:20.000" });
  });
});
