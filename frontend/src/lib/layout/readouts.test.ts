import { describe, expect, it } from "vitest";
import type { Frame } from "../../generated/layout";
import { frameField } from "./layoutInfo";
import {
  JOINT_COLUMNS,
  NO_VALUE,
  TCP_ROWS,
  decimalsFor,
  formatReadout,
  headerWithUnit,
  shortTitle,
  updateTexts,
  type ReadoutCell,
} from "./readouts";

describe("readout columns", () => {
  it("lists the six joint quantities with the layout's units and joint labels", () => {
    expect(JOINT_COLUMNS.map((c) => c.field)).toEqual([
      "joint_position",
      "joint_velocity",
      "joint_motor_current",
      "joint_motor_temperature",
      "joint_torque",
      "joint_external_torque",
    ]);
    expect(JOINT_COLUMNS.map(headerWithUnit)).toEqual([
      "Position [degree]",
      "Velocity [degree/s]",
      "Motor current [A]",
      "Motor temperature [°C]",
      "Torque [N·m]",
      "External torque [N·m]",
    ]);
    for (const c of JOINT_COLUMNS) {
      expect(c.unit).toBe(frameField(c.field).unit);
      expect(c.channels).toHaveLength(6);
    }
  });

  it("lists TCP pose, velocity, force and moment with three elements each", () => {
    expect(TCP_ROWS.map(headerWithUnit)).toEqual([
      "Position [mm]",
      "Orientation [degree]",
      "Velocity [mm/s]",
      "Angular velocity [degree/s]",
      "External force [N]",
      "External moment [N·m]",
    ]);
    expect(TCP_ROWS.every((r) => r.channels.length === 3)).toBe(true);
  });

  it("shortens the layout's descriptions", () => {
    expect(shortTitle("Joint 1–6 motor temperature")).toBe("Motor temperature");
    expect(shortTitle("TCP angular velocity RX, RY, RZ (base frame)")).toBe("Angular velocity");
    expect(shortTitle("External force X, Y, Z (base frame)")).toBe("External force");
  });
});

describe("formatReadout", () => {
  it("uses fixed decimals and a real minus sign", () => {
    expect(formatReadout(12.3456, 2)).toBe("12.35");
    expect(formatReadout(-7.25, 1)).toBe("\u22127.3");
    expect(formatReadout(3, 2)).toBe("3.00");
  });

  it("never shows negative zero", () => {
    expect(formatReadout(-0.0001, 2)).toBe("0.00");
    expect(formatReadout(-0, 1)).toBe("0.0");
  });

  it("shows a dash for no value", () => {
    expect(formatReadout(null, 2)).toBe(NO_VALUE);
    expect(formatReadout(undefined, 2)).toBe(NO_VALUE);
    expect(formatReadout(Number.NaN, 2)).toBe(NO_VALUE);
  });

  it("gives each unit a precision, 2 for one it does not know", () => {
    expect(decimalsFor("°C")).toBe(1);
    expect(decimalsFor("degree")).toBe(2);
    expect(decimalsFor("furlong")).toBe(2);
  });
});

describe("updateTexts", () => {
  const cells: ReadoutCell[] = [
    { field: "joint_position", index: 0, decimals: 2 },
    { field: "joint_position", index: 1, decimals: 2 },
    { field: "tcp_position", index: 2, decimals: 1 },
  ];
  const frame = (j0: number, j1: number | null, z: number) =>
    ({ joint_position: [j0, j1, 0, 0, 0, 0], tcp_position: [0, 0, z] }) as unknown as Frame;

  it("reports only the cells whose text changed", () => {
    const texts = ["", "", ""];
    const changed = [0, 0, 0];
    expect(updateTexts(frame(1, 2, 3), cells, texts, changed)).toBe(3);
    expect(texts).toEqual(["1.00", "2.00", "3.0"]);
    // 1.001 rounds to the same text: not touched.
    const count = updateTexts(frame(1.001, null, 3.5), cells, texts, changed);
    expect(changed.slice(0, count)).toEqual([1, 2]);
    expect(texts).toEqual(["1.00", NO_VALUE, "3.5"]);
  });

  it("shows dashes before the first frame", () => {
    const texts = ["x", "x", "x"];
    const changed = [0, 0, 0];
    expect(updateTexts(null, cells, texts, changed)).toBe(3);
    expect(texts).toEqual([NO_VALUE, NO_VALUE, NO_VALUE]);
  });
});
