import { describe, expect, it } from "vitest";
import { changeLines, importBody, parsePresetItems, presetWords, type Preset } from "./presets";

const JOB: Preset = {
  name: "Job 3",
  items: { "bit_input_registers.0": true, "bit_input_registers.1": true },
  labels: { "bit_input_registers.0": "Register in 0", "bit_input_registers.1": "Register in 1" },
  created_at: 1,
  created_by: "olivia",
  builtin: false,
};

describe("presets", () => {
  it("lists the changes for the confirmation", () => {
    expect(
      changeLines([
        { key: "bit_input_registers.0", label: "Register in 0", from: false, to: true },
        { key: "analog_output.0", label: "AO 0", from: 4, to: 12.5 },
      ]),
    ).toEqual(["Register in 0: off → on", "AO 0: 4 → 12.5"]);
  });

  it("reads the JSON export (without the built-in preset) and the CSV export", () => {
    const exported = JSON.stringify({ robot: "robot", items: [{ ...JOB, name: "All outputs off", builtin: true }, JOB] });
    expect(importBody(exported, "robot-presets.json")).toEqual({ items: [{ name: "Job 3", items: JOB.items }] });
    const csv = "preset,key,label,value\nJob 3,bit_input_registers.0,Register in 0,1\n";
    expect(importBody(csv, "robot-presets.csv")).toEqual({ csv });
    expect(importBody("hello", "notes.txt")).toBeNull();
    expect(importBody("{not json", "x.json")).toBeNull();
  });

  it("shortens a long preset in words", () => {
    expect(presetWords(JOB)).toBe("Register in 0, Register in 1");
    const many = Object.fromEntries(Array.from({ length: 6 }, (_, i) => [`controlbox_do.${i}`, `DO ${i + 1}`]));
    expect(presetWords({ ...JOB, labels: many })).toBe("DO 1, DO 2, DO 3, DO 4 … (6 values)");
  });

  it("reads values typed by hand by label or key", () => {
    expect(parsePresetItems("DO 3 = on, register in 12=0\nAO 0 = 12.5; tool_do.1 = true")).toEqual({
      ok: true,
      items: { "controlbox_do.2": true, "bit_input_registers.12": false, "analog_output.0": 12.5, "tool_do.1": true },
    });
    const wrong = (text: string) => {
      const parsed = parsePresetItems(text);
      return parsed.ok ? null : parsed.reason;
    };
    expect(wrong("DI 5 = on")).toContain("not an output");
    expect(wrong("DO 3 = maybe")).toContain("a bit is on or off");
    expect(wrong("AO 1 = high")).toContain("takes a number");
    expect(wrong(" , ")).toContain("no values");
  });
});
