/**
 * Layer: pure kiosk logic (no React, no DOM, no network).
 *
 * The kiosk's large numeric tiles are chosen in its URL (`/kiosk?robot=NAME&tiles=joint_position,
 * tcp_position`): any numeric field of the robot's frame, by its layout name. Names, channel
 * labels and units come from the generated layout; this module decides only how many decimals a
 * number gets (fixed per field, so digits do not jump about as values change) and how a state
 * reads in plain words (a few, for the person at the cell: not the manual's sentence).
 */
import { LAYOUT, type FieldInfo, type Frame, type FrameFieldName, type RobotStateName } from "../../generated/layout";
import { CYCLE_TILE, CYCLE_TILE_DECIMALS, CYCLE_TILE_NAME } from "./cyclesTile";
import type { TileShape } from "./kioskLayout";
import { stateBadge } from "../layout/stateBadge";

/** Tiles shown when the URL chooses none. */
export const DEFAULT_TILES: readonly FrameFieldName[] = ["joint_position", "tcp_position"];

const T2O = LAYOUT.assemblies.find((a) => a.direction === "T2O");

/** Fields a tile can show: numbers (not bits, not the state, which the kiosk shows anyway). */
export const TILE_FIELDS: readonly FieldInfo[] = (T2O?.fields ?? []).filter(
  (f) => f.value_kind !== "bool" && f.enum === undefined && f.element_names === undefined && f.name !== "robot_state",
);

// Beside the frame's numbers: the robot's cycle time (`tiles=cycle_time`, lib/kiosk/cyclesTile.ts).
const BY_NAME = new Map([...TILE_FIELDS, CYCLE_TILE].map((f) => [f.name, f]));

export interface TileChoice {
  readonly fields: readonly FieldInfo[];
  /** Names in the URL that are no numeric field of the frame (shown, so a typo is seen). */
  readonly unknown: readonly string[];
}

/** The tiles a kiosk URL's query asks for (`tiles=a,b`; repeated `tiles` add up). */
export function tilesFromSearch(search: string): TileChoice {
  const params = new URLSearchParams(search);
  const asked = params
    .getAll("tiles")
    .flatMap((v) => v.split(","))
    .map((v) => v.trim())
    .filter((v) => v !== "");
  if (asked.length === 0) return { fields: DEFAULT_TILES.map((n) => BY_NAME.get(n)).filter((f): f is FieldInfo => f !== undefined), unknown: [] };
  const fields: FieldInfo[] = [];
  const unknown: string[] = [];
  for (const name of asked) {
    const field = BY_NAME.get(name.toLowerCase());
    if (field === undefined) unknown.push(name);
    else if (!fields.includes(field)) fields.push(field);
  }
  return { fields, unknown };
}

/** Decimals of a field's numbers: whole numbers for integers, two for currents and analog. */
export function tileDecimals(field: FieldInfo): number {
  if (field.value_kind === "int") return 0;
  if (field.unit === "A" || field.unit.startsWith("mA")) return 2;
  return 1;
}

/** One number as a tile shows it: fixed decimals, a real minus sign, no "-0.0", "—" for none. */
export function formatTileValue(value: unknown, field: FieldInfo, decimals = tileDecimals(field)): string {
  if (typeof value !== "number" || !Number.isFinite(value)) return "—";
  const text = value.toFixed(decimals);
  if (/^-0(\.0+)?$/.test(text)) return text.slice(1);
  return text.startsWith("-") ? `\u2212${text.slice(1)}` : text;
}

/** Whole-number digits a field's values are given room for (by unit; a minus sign apart). */
function integerDigits(field: FieldInfo): number {
  if (field.value_kind === "int") return 5;
  if (field.unit === "degree" || field.unit === "°C" || field.unit.startsWith("deg")) return 3;
  if (field.unit === "A" || field.unit.startsWith("mA")) return 2;
  return 4;
}

/**
 * What a tile of `field` needs room for (lib/kiosk/kioskLayout.ts sizes the grid from it): its cells,
 * its longest value ("−1234.5"), label and title with the unit.
 */
export function tileShape(field: FieldInfo): TileShape {
  const decimals = tileDecimals(field);
  const labels = field.channels.length > 0 ? field.channels : [field.description];
  return {
    cells: labels.length,
    valueChars: 1 + integerDigits(field) + (decimals > 0 ? 1 + decimals : 0),
    labelChars: Math.max(...labels.map((l) => l.length)),
    titleChars: field.description.length + (field.unit !== "" ? field.unit.length + 3 : 0),
  };
}

export interface TileCell {
  readonly label: string;
  readonly text: string;
  /** The cycle tile's last cycle when it was slow (lib/kiosk/cyclesTile.ts): marked beside it. */
  readonly slow?: true;
}

/** Each channel of `field` in `frame` with its layout label ("J1", "X", …). */
export function tileCells(field: FieldInfo, frame: Frame | null): TileCell[] {
  const raw: unknown = frame === null ? undefined : (frame as unknown as Record<string, unknown>)[field.name];
  const values: readonly unknown[] = Array.isArray(raw) ? raw : [raw];
  const labels = field.channels.length > 0 ? field.channels : [field.description];
  if (field.name === CYCLE_TILE_NAME) {
    const slow = frame !== null && (frame as unknown as Record<string, unknown>).cycle_time_slow === true;
    return labels.map((label, i) => ({
      label,
      text: formatTileValue(values[i], field, CYCLE_TILE_DECIMALS[i]),
      ...(i === 0 && slow ? { slow: true as const } : {}),
    }));
  }
  return labels.map((label, i) => ({ label, text: formatTileValue(values[i], field) }));
}

/** "STANDALONE_RUNNING" → "Standalone running". */
export function plainName(name: string): string {
  const words = name.toLowerCase().replace(/_/g, " ");
  return words.charAt(0).toUpperCase() + words.slice(1);
}

/**
 * What each state means to the person at the cell, in a few words read from 3 m (issue 38: the
 * subtitle was the manual's sentence, "The Teach Pendant UI is in the actual mode execution
 * screen in a single work space."). Every state has one: the type makes a new state in the layout
 * a compile error here until it has its words.
 */
const STATE_SUBTITLES: Readonly<Record<RobotStateName, string>> = {
  EMERGENCY_STOP: "Emergency stop pressed: release it and reset",
  INITIALIZING: "Starting up",
  SAFE_OFF: "Servo off after an error: reset to go on",
  INTERRUPTED: "Protective stop: clear the cause and reset",
  MANUAL_STANDBY: "Teaching, waiting",
  MANUAL_JOGGING: "Teaching, being jogged",
  MANUAL_HANDGUIDING: "Teaching, being moved by hand",
  RECOVERY_STANDBY: "Recovery, safety limits off: waiting",
  RECOVERY_JOGGING: "Recovery: being jogged back within its limits",
  BACKDRIVE_HOLD: "Brakes on, backdrive locked",
  BACKDRIVE_RELEASE: "A joint's brake is released",
  BACKDRIVE_RELEASE_BY_COCKPIT: "A joint's brake is released from the Cockpit",
  RECOVERY_HANDGUIDING: "Recovery: being moved by hand back within its limits",
  STANDALONE_STANDBY: "Ready, no program running",
  STANDALONE_RUNNING: "Running its program",
  COLLABORATIVE_STANDBY: "Ready, no program running (collaborative zone)",
  COLLABORATIVE_RUNNING: "Running its program (collaborative zone)",
  HIGH_PRIORITY_RUNNING: "Running its program (high-priority zone)",
  AUTO_MEASURE: "Measuring the tool's weight and centre of gravity",
  HANDGUIDING_CONTROL_STANDBY: "Program waiting to be guided by hand",
  HANDGUIDING_CONTROL_RUNNING: "Program: being guided by hand",
};

/**
 * The robot's state in plain words: the layout's state name as a phrase and what it means at the
 * cell ("Standalone standby", "Ready, no program running"), never the manual's sentence.
 */
export function stateWords(value: number | null | undefined): { readonly title: string; readonly detail: string } {
  const badge = stateBadge(value);
  if (!badge.known) return { title: value === null || value === undefined ? "No data" : "Unknown state", detail: badge.description };
  return { title: plainName(badge.name), detail: STATE_SUBTITLES[badge.name as RobotStateName] };
}
