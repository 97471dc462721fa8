import { describe, expect, it } from "vitest";
import { analogRange, analogUnit, channelNumber, commandField, FLAG_FIELDS, flagEnumName, frameField, kebab, keyLabel } from "./layoutInfo";

describe("layout lookups", () => {
  it("lists the five flags with their full names, in the layout's order", () => {
    expect(FLAG_FIELDS.map((f) => kebab(f.name))).toEqual([
      "servo-on",
      "safety-stopped",
      "emergency-stopped",
      "direct-teach-button-pressed",
      "power-button-pressed",
    ]);
    expect(FLAG_FIELDS.every((f) => (f.flag?.full_name ?? "") !== "")).toBe(true);
  });

  it("names each flag in plain words and keeps the robot's own name for the tooltip", () => {
    expect(FLAG_FIELDS.map((f) => f.description)).toContain("Servo on");
    expect(flagEnumName(frameField("servo_on"))).toBe("SERVO_ON_ROBOT, SO");
  });

  it("numbers test ids as the robot labels its channels", () => {
    expect(frameField("controlbox_di").channels.map(channelNumber)).toEqual(Array.from({ length: 16 }, (_, i) => i + 1));
    expect(frameField("analog_input").channels.map(channelNumber)).toEqual([0, 1]);
    expect(commandField("bit_input_registers").channels.map(channelNumber)).toEqual(Array.from({ length: 64 }, (_, i) => i));
    expect(frameField("tool_do").channels.map(channelNumber)).toEqual([1, 2, 3, 4, 5, 6]);
  });

  it("gives analog ranges and units per type from the layout", () => {
    const type = commandField("analog_output_type");
    expect(analogRange(type, 0)).toEqual({ low: 4, high: 20, unit: "mA" });
    expect(analogRange(type, 1)).toEqual({ low: 0, high: 10, unit: "V" });
    expect(analogRange(type, 7)).toBeNull();
    expect(analogUnit(frameField("analog_input_type"), 1)).toBe("V");
  });

  it("names the API's field.index keys by the layout's channel labels", () => {
    expect(keyLabel("controlbox_do.2")).toBe("DO 3");
    expect(keyLabel("tool_do.0")).toBe("Tool DO 1");
    expect(keyLabel("analog_output.1")).toBe("AO 1");
    expect(keyLabel("bit_input_registers.40")).toBe("bit input Register 40");
    expect(keyLabel("nonsense.3")).toBe("nonsense.3");
    expect(keyLabel("controlbox_do.99")).toBe("controlbox_do.99");
  });
});
