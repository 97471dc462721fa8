/**
 * Layer: pure description and formatting of the numeric readouts (no React, no DOM, no network).
 *
 * The joint table and the TCP readout show the newest frame's numbers beside the plots. Which
 * fields, their names, units and channel labels come from the generated layout (through
 * `layoutInfo`); this module only chooses the order, the short column titles and how many
 * decimals a unit is shown with. Must not import React or any component.
 */
import type { Frame, FrameFieldName } from "../../generated/layout";
import { frameField } from "./layoutInfo";

/** The array fields of a frame that hold numbers (joint and TCP monitoring). */
export type NumericFieldName =
  | "joint_position"
  | "joint_velocity"
  | "joint_motor_current"
  | "joint_motor_temperature"
  | "joint_torque"
  | "joint_external_torque"
  | "tcp_position"
  | "tcp_orientation"
  | "tcp_velocity"
  | "tcp_angular_velocity"
  | "external_force"
  | "external_moment";

/** One readout quantity: a layout field, its short title, unit and element labels. */
export interface ReadoutColumn {
  readonly field: NumericFieldName;
  /** Short title from the layout's description ("Joint 1–6 motor current" → "Motor current"). */
  readonly title: string;
  /** The layout's unit ("degree", "N·m"). */
  readonly unit: string;
  /** The layout's channel labels ("J 1" … "J 6", "X", "Y", "Z"). */
  readonly channels: readonly string[];
  readonly decimals: number;
}

/**
 * Decimals per unit: enough to see the robot move at the monitoring rate, no more than the
 * values carry (REAL, about 7 significant digits). Units the layout adds later get 2.
 */
const DECIMALS_BY_UNIT: Readonly<Record<string, number>> = {
  degree: 2,
  "degree/s": 2,
  A: 2,
  "°C": 1,
  "N·m": 2,
  mm: 1,
  "mm/s": 1,
  N: 1,
};

export function decimalsFor(unit: string): number {
  return DECIMALS_BY_UNIT[unit] ?? 2;
}

/** The layout's description without its channel range and frame note, capitalised. */
export function shortTitle(description: string): string {
  const bare = description
    .replace(/\s*\(.*\)\s*$/, "") // "(base frame)"
    .replace(/^Joint\s+\d+\s*[–-]\s*\d+\s+/, "") // "Joint 1–6 "
    .replace(/^TCP\s+/, "")
    .replace(/\s+[A-Z]{1,2}(,\s*[A-Z]{1,2})+$/, ""); // " X, Y, Z", " RX, RY, RZ"
  return bare.charAt(0).toUpperCase() + bare.slice(1);
}

function column(field: NumericFieldName): ReadoutColumn {
  const info = frameField(field as FrameFieldName);
  return {
    field,
    title: shortTitle(info.description),
    unit: info.unit,
    channels: info.channels,
    decimals: decimalsFor(info.unit),
  };
}

/** The joint table's columns, in the order: one row per joint. */
export const JOINT_COLUMNS: readonly ReadoutColumn[] = (
  [
    "joint_position",
    "joint_velocity",
    "joint_motor_current",
    "joint_motor_temperature",
    "joint_torque",
    "joint_external_torque",
  ] as const
).map(column);

/** The TCP readout's rows: pose, velocity, force and moment, each with its three elements. */
export const TCP_ROWS: readonly ReadoutColumn[] = (
  ["tcp_position", "tcp_orientation", "tcp_velocity", "tcp_angular_velocity", "external_force", "external_moment"] as const
).map(column);

/** A column header with its unit: "Position [degree]". */
export function headerWithUnit(column: ReadoutColumn): string {
  return column.unit === "" ? column.title : `${column.title} [${column.unit}]`;
}

/** The dash shown for a value the frame does not have (no frame yet, non-finite REAL). */
export const NO_VALUE = "—";

/**
 * A readout's text: fixed decimals, a real minus sign, never "-0.00" (a value that rounds to
 * zero is shown as zero, so a resting joint does not flicker between signs).
 */
export function formatReadout(value: number | null | undefined, decimals: number): string {
  if (value === null || value === undefined || !Number.isFinite(value)) return NO_VALUE;
  const text = value.toFixed(decimals);
  if (Number(text) === 0) return (0).toFixed(decimals);
  return text.startsWith("-") ? `\u2212${text.slice(1)}` : text;
}

/** The value of `field[index]` in `frame` (null when absent). */
export function frameValue(frame: Frame | null, field: NumericFieldName, index: number): number | null {
  if (frame === null) return null;
  const value = frame[field][index];
  return value === undefined ? null : value;
}

/** One cell of a readout: where its value comes from and how it is written. */
export interface ReadoutCell {
  readonly field: NumericFieldName;
  readonly index: number;
  readonly decimals: number;
}

/**
 * The texts of `cells` for `frame`, written into `out` (reused: no allocation per frame); returns
 * the indices whose text changed since `out` was last filled, so a view touches only those.
 */
export function updateTexts(frame: Frame | null, cells: readonly ReadoutCell[], out: string[], changed: number[]): number {
  let count = 0;
  for (let i = 0; i < cells.length; i++) {
    const cell = cells[i];
    if (cell === undefined) continue;
    const text = formatReadout(frameValue(frame, cell.field, cell.index), cell.decimals);
    if (out[i] !== text) {
      out[i] = text;
      changed[count++] = i;
    }
  }
  return count;
}
