import { describe, expect, it } from "vitest";
import {
  countsWords,
  evidenceWords,
  filterPoints,
  openCheckout,
  pointTime_s,
  pointWho,
  verdictRefusal,
  type CheckoutPoint,
  type CheckoutSummary,
} from "./checkout";

function point(over: Partial<CheckoutPoint>): CheckoutPoint {
  return {
    key: "controlbox_di.4",
    label: "DI 5",
    tag: null,
    kind: "input",
    signal: "digital",
    result: "untested",
    seen_at: null,
    seen_before: null,
    seen_after: null,
    samples: [],
    switched_at: null,
    switched_value: null,
    switched_by: null,
    switches: [],
    recorded_at: null,
    recorded_by: null,
    comment: null,
    ...over,
  };
}

const DI5 = point({ tag: "door switch", result: "seen", seen_at: 10, seen_before: false, seen_after: true });
const DO3 = point({ key: "controlbox_do.2", label: "DO 3", kind: "output", result: "pass", switched_at: 11, switched_value: true, switched_by: "olivia", recorded_at: 12, recorded_by: "oscar", comment: "moved" });
const AI0 = point({ key: "analog_input.0", label: "AI 0", signal: "analog", samples: [{ time: 5, value: 4, by: "ada" }, { time: 6, value: 20, by: "olivia" }], result: "seen" });
const REG = point({ key: "bit_input_registers.12", label: "Register in 12", kind: "output" });

describe("checkout points", () => {
  it("filters by kind, verdict and text (label, key or tag)", () => {
    const all = [DI5, DO3, AI0, REG];
    expect(filterPoints(all, "inputs", "").map((p) => p.label)).toEqual(["DI 5", "AI 0"]);
    expect(filterPoints(all, "outputs", "").map((p) => p.label)).toEqual(["DO 3", "Register in 12"]);
    expect(filterPoints(all, "open", "").map((p) => p.label)).toEqual(["DI 5", "AI 0", "Register in 12"]);
    expect(filterPoints(all, "done", "").map((p) => p.label)).toEqual(["DI 5", "DO 3", "AI 0"]);
    expect(filterPoints(all, "all", "DOOR").map((p) => p.label)).toEqual(["DI 5"]);
    expect(filterPoints(all, "all", "register in").map((p) => p.label)).toEqual(["Register in 12"]);
    expect(filterPoints(all, "all", "analog_input").map((p) => p.label)).toEqual(["AI 0"]);
  });

  it("says what the robot showed, when and who", () => {
    expect(evidenceWords(DI5)).toBe("off → on");
    expect(evidenceWords(DO3)).toBe("on (confirmed)");
    expect(evidenceWords(AI0)).toBe("4.000, 20.000");
    expect(evidenceWords(REG)).toBe("");
    expect(pointTime_s(DO3)).toBe(12);
    expect(pointTime_s(AI0)).toBe(6);
    expect(pointTime_s(REG)).toBeNull();
    expect(pointWho(DO3)).toBe("oscar");
    expect(pointWho(AI0)).toBe("olivia");
    expect(pointWho(DI5)).toBe("");
  });

  it("keeps every switch of an output with its confirmation time (issue 38)", () => {
    const clock = (ms: number) => `t${ms / 1000}`;
    const onThenOff = point({
      ...DO3,
      switched_at: 14,
      switched_value: false,
      switches: [
        { time: 11, value: true, by: "olivia", latency_ms: 12, seq: 100 },
        { time: 14, value: false, by: "olivia", latency_ms: 11, seq: 400 },
      ],
    });
    expect(evidenceWords(onThenOff, clock)).toBe("on confirmed t11, off confirmed t14");
    const ao = point({ key: "analog_output.0", label: "AO 0", kind: "output", signal: "analog", switches: [{ time: 3, value: 12.5, by: "ada", latency_ms: null }] });
    expect(evidenceWords(ao, clock)).toBe("12.5 confirmed t3");
  });

  it("asks a comment of a fail and offers the open checkout to resume (issue 38)", () => {
    expect(verdictRefusal("fail", "  ")).toBe("A fail needs a comment saying what is wrong.");
    expect(verdictRefusal("fail", "no wire")).toBeNull();
    expect(verdictRefusal("pass", "")).toBeNull();
    const summary = (id: number, closed_at: number | null): CheckoutSummary => ({
      id,
      robot: "robot",
      started_at: id,
      started_by: "olivia",
      closed_at,
      closed_by: closed_at === null ? null : "olivia",
      identity: null,
      counts: { untested: 176, seen: 0, pass: 0, fail: 0 },
    });
    expect(openCheckout([summary(3, null), summary(2, 5)])?.id).toBe(3);
    expect(openCheckout([summary(2, 5)])).toBeNull();
  });

  it("counts in words", () => {
    expect(countsWords({ pass: 2, fail: 1, seen: 3, untested: 170 })).toBe("2 pass, 1 fail, 3 seen, 170 untested");
  });
});
