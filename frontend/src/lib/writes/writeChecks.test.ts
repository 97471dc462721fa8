import { describe, expect, it } from "vitest";
import type { Frame } from "../../generated/layout";
import { analogRange, channelNumber, commandField, keyLabel } from "../layout/layoutInfo";
import { checkSetpoint, parseDecimal, stopWarning } from "./writeChecks";

const current = analogRange(commandField("analog_output_type"), 0);
const voltage = analogRange(commandField("analog_output_type"), 1);

describe("parseDecimal", () => {
  it.each([
    ["12.5", 12.5],
    ["12,5", 12.5],
    [" -3 ", -3],
    ["\u22124,25", -4.25],
    [",5", 0.5],
    ["+7", 7],
    ["10.", 10],
  ])("reads %j as %d", (text, value) => {
    expect(parseDecimal(text)).toEqual({ ok: true, value });
  });

  it.each(["", "  ", "abc", "1,234.5", "1.2.3", "1e3", "12 mA", "--1", "Infinity"])("refuses %j", (text) => {
    expect(parseDecimal(text).ok).toBe(false);
  });
});

describe("checkSetpoint", () => {
  it("takes the layout's ranges: 4–20 mA for current, 0–10 V for voltage", () => {
    expect(current).toEqual({ low: 4, high: 20, unit: "mA" });
    expect(checkSetpoint("12,5", current)).toEqual({ ok: true, value: 12.5 });
    expect(checkSetpoint("4", current)).toEqual({ ok: true, value: 4 });
    expect(checkSetpoint("20,0", current)).toEqual({ ok: true, value: 20 });
    expect(checkSetpoint("0", voltage)).toEqual({ ok: true, value: 0 });
  });

  it("refuses a value outside the range and says the range", () => {
    const refused = checkSetpoint("25", current);
    expect(refused.ok).toBe(false);
    if (!refused.ok) expect(refused.reason).toBe("out of range: 4–20 mA");
    expect(checkSetpoint("3,99", current).ok).toBe(false);
    expect(checkSetpoint("10,01", voltage).ok).toBe(false);
    expect(checkSetpoint("-0,5", voltage).ok).toBe(false);
  });

  it("a value that was out of range for one type can be valid for the other", () => {
    expect(checkSetpoint("2", current).ok).toBe(false);
    expect(checkSetpoint("2", voltage).ok).toBe(true);
  });

  it("refuses what is not a number before looking at the range", () => {
    const refused = checkSetpoint("x", current);
    expect(refused.ok).toBe(false);
    if (!refused.ok) expect(refused.reason).toContain("not a number");
  });
});

describe("stopWarning", () => {
  const frame = (over: Partial<Frame>) =>
    ({ robot_state_name: "STANDALONE_RUNNING", emergency_stopped: false, safety_stopped: false, ...over }) as Frame;

  it("warns during an emergency stop and a protective stop, in the layout's words", () => {
    expect(stopWarning(frame({ emergency_stopped: true }))).toContain("emergency stop");
    expect(stopWarning(frame({ robot_state_name: "EMERGENCY_STOP" }))).toContain("emergency stop");
    expect(stopWarning(frame({ safety_stopped: true }))).toContain("protective stop");
    expect(stopWarning(frame({ robot_state_name: "INTERRUPTED" }))).toContain("protective stop");
  });

  it("says nothing while the robot runs or before a frame", () => {
    expect(stopWarning(frame({}))).toBeNull();
    expect(stopWarning(null)).toBeNull();
  });
});

describe("numbering without traps", () => {
  it("shows the robot's own labels for the API's 0-based indices", () => {
    expect(keyLabel("controlbox_do.2")).toBe("DO 3");
    expect(keyLabel("controlbox_do.15")).toBe("DO 16");
    expect(keyLabel("tool_do.0")).toBe("Tool DO 1");
    expect(keyLabel("analog_output.1")).toBe("AO 1");
    expect(keyLabel("bit_input_registers.63")).toContain("63");
  });

  it("numbers DO 1–16, tool DO 1–6, AO 0–1 and registers 0–63 as the spec does", () => {
    const numbers = (field: Parameters<typeof commandField>[0]) => commandField(field).channels.map(channelNumber);
    expect(numbers("controlbox_do")).toEqual(Array.from({ length: 16 }, (_, i) => i + 1));
    expect(numbers("tool_do")).toEqual([1, 2, 3, 4, 5, 6]);
    expect(numbers("analog_output")).toEqual([0, 1]);
    expect(numbers("bit_input_registers")).toEqual(Array.from({ length: 64 }, (_, i) => i));
  });
});
