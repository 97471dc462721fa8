/**
 * Layer: pure layout lookups (no React, no DOM, no network).
 *
 * Everything the UI knows about fields, units, channel labels, flags, analog types and ranges is
 * derived here from the generated layout module (`../generated/layout`), the only source of those
 * names in the frontend. Must not import React, Plotly or any component.
 */
import {
  LAYOUT,
  type AnalogRange,
  type CommandFieldName,
  type FieldInfo,
  type FrameFieldName,
} from "../../generated/layout";

function assembly(direction: "T2O" | "O2T") {
  const found = LAYOUT.assemblies.find((a) => a.direction === direction);
  if (found === undefined) throw new Error(`layout has no ${direction} assembly`);
  return found;
}

const T2O_FIELDS = new Map<string, FieldInfo>(assembly("T2O").fields.map((f) => [f.name, f]));
const O2T_FIELDS = new Map<string, FieldInfo>(assembly("O2T").fields.map((f) => [f.name, f]));

/** The T→O (robot → PLC) field called `name`. */
export function frameField(name: FrameFieldName): FieldInfo {
  const field = T2O_FIELDS.get(name);
  if (field === undefined) throw new Error(`layout has no T→O field ${name}`);
  return field;
}

/** The O→T (PLC → robot) field called `name`. */
export function commandField(name: CommandFieldName): FieldInfo {
  const field = O2T_FIELDS.get(name);
  if (field === undefined) throw new Error(`layout has no O→T field ${name}`);
  return field;
}

/** The five status flags of the robot, in the layout's order. */
export const FLAG_FIELDS: readonly FieldInfo[] = assembly("T2O").fields.filter(
  (f) => f.flag !== undefined,
);

/** Frame field names of the flags, typed (the layout's names are the JSON keys of a Frame). */
export type FlagFieldName =
  | "servo_on"
  | "safety_stopped"
  | "emergency_stopped"
  | "direct_teach_button_pressed"
  | "power_button_pressed";

/** The robot's own name of a flag and its abbreviation ("SERVO_ON_ROBOT, SO"), for tooltips. */
export function flagEnumName(field: FieldInfo): string {
  if (field.flag === undefined) return field.name;
  return `${field.flag.full_name}, ${field.flag.abbreviation}`;
}

export function isFlagField(name: string): name is FlagFieldName {
  return FLAG_FIELDS.some((f) => f.name === name);
}

/** `servo_on` → `servo-on`: the layout's field name as it appears in test ids. */
export function kebab(name: string): string {
  return name.replace(/_/g, "-");
}

/**
 * The number a channel label ends with ("DI 3" → 3, "Register 40" → 40, "AI 0" → 0). Test ids
 * use the robot's own numbering, which the layout's labels carry (1-based for digital I/O,
 * 0-based for analog channels and registers).
 */
export function channelNumber(label: string): number {
  const match = /(\d+)\s*$/.exec(label);
  if (match === null || match[1] === undefined) throw new Error(`channel label ${label} has no number`);
  return Number(match[1]);
}

/** Name of an analog type value (0 → "current", 1 → "voltage") from the field's value names. */
export function analogTypeName(field: FieldInfo, value: number | null | undefined): string | null {
  if (value === null || value === undefined) return null;
  return field.value_names?.[value] ?? null;
}

/** Range and unit of an analog output of the given type, from the layout. */
export function analogRange(field: FieldInfo, typeValue: number | null | undefined): AnalogRange | null {
  const name = analogTypeName(field, typeValue);
  if (name === null) return null;
  return LAYOUT.analog_output_ranges[name] ?? null;
}

/**
 * The unit of an analog channel of the given type. The layout gives the analog fields a unit
 * "per its type"; the per-type units live in `analog_output_ranges` (the same for inputs).
 */
export function analogUnit(field: FieldInfo, typeValue: number | null | undefined): string {
  return analogRange(field, typeValue)?.unit ?? "";
}

/** "Joint 1–6 position" → "position"; used as a short plot title beside the group name. */
export function fieldTitle(field: FieldInfo): string {
  return field.description;
}

/**
 * A person's name for a "field.index" key of the API's audit and events ("controlbox_do.2" →
 * "DO 3"), from the layout's channel labels; the key itself when the layout has no label for it.
 */
export function keyLabel(key: string): string {
  const dot = key.lastIndexOf(".");
  if (dot < 0) return key;
  const name = key.slice(0, dot);
  const index = Number(key.slice(dot + 1));
  const field = O2T_FIELDS.get(name) ?? T2O_FIELDS.get(name);
  const label = Number.isInteger(index) ? field?.channels[index] : undefined;
  if (label === undefined) return key;
  return name === "bit_input_registers" ? `bit input ${label}` : label;
}
