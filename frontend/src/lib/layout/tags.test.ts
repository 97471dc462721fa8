import { describe, expect, it } from "vitest";
import { bitClickRequest, bitWriteQuestion, pointsWords, pointWords, tagChanges } from "./tags";

describe("tag names beside the spec's labels", () => {
  it("names a 0-based key by its label and its tag", () => {
    expect(pointWords("controlbox_do.2", { "controlbox_do.2": "gripper close" })).toBe("DO 3 — gripper close");
    expect(pointWords("controlbox_do.2", {})).toBe("DO 3");
    expect(pointWords("tool_do.0", null)).toBe("Tool DO 1");
    expect(pointWords("analog_output.0", { "analog_output.0": "pump" })).toBe("AO 0 — pump");
  });

  it("prefers the service's own labels when an answer carries them", () => {
    expect(pointWords("analog_output_type.1", null, { "analog_output_type.1": "AO 1 type" })).toBe("AO 1 type");
    expect(pointWords("bit_input_registers.40", { "bit_input_registers.40": "part ready" }, { "bit_input_registers.40": "Register 40" })).toBe(
      "Register 40 — part ready",
    );
  });

  it("joins several points, a dash for none", () => {
    expect(pointsWords(["controlbox_do.2", "controlbox_do.3"], { "controlbox_do.3": "lamp" })).toBe("DO 3, DO 4 — lamp");
    expect(pointsWords([], null)).toBe("—");
  });

  it("counts the names changed (an empty name is none)", () => {
    expect(tagChanges({ a: "x" }, { a: "x" })).toBe(0);
    expect(tagChanges({ a: "x" }, { a: "y", b: "" })).toBe(1);
    expect(tagChanges({ a: "x" }, { a: "", b: "z" })).toBe(2);
  });
});

describe("bitWriteQuestion", () => {
  it("says a register is a register, and names the point's tag", () => {
    expect(bitWriteQuestion("register", "5", undefined, true)).toBe("Set bit input register 5 ON?");
    expect(bitWriteQuestion("register", "5", "part present", false)).toBe("Set bit input register 5 (part present) OFF?");
    expect(bitWriteQuestion("output", "DO 3", "gripper close", true)).toBe("Switch DO 3 (gripper close) ON?");
    expect(bitWriteQuestion("output", "DO 3", " ", true)).toBe("Switch DO 3 ON?");
  });
});

describe("what a click on a bit asks for", () => {
  it("is the opposite of what the toggle shows, even before the frames show a confirmed write", () => {
    // Confirmed ON, the toggle holds ON, the last frame still says off: the click asks OFF.
    expect(bitClickRequest(true, false, true)).toBe(false);
    expect(bitClickRequest(false, true, false)).toBe(true);
  });

  it("falls back on the robot's state, then the command, when the toggle shows no value", () => {
    expect(bitClickRequest(null, true, false)).toBe(false);
    expect(bitClickRequest(null, null, true)).toBe(false);
    expect(bitClickRequest(null, null, null)).toBe(true);
    expect(bitClickRequest("pending", false, true)).toBe(true);
  });
});
