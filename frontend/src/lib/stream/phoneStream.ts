/**
 * Layer: pure panel logic (no React, no DOM, no network): what a narrow screen's panel asks of
 * its stream (issue 38). A phone shows a few sections at a time and redraws its numbers a few
 * times a second, so it asks for the fields of the sections in view (and the header's: the state
 * and the flags) at `PHONE_RATE_HZ`, instead of every field of every frame (235 KiB/s before).
 * A wide screen asks for everything: its plots draw every frame.
 */
import { FLAG_FIELDS } from "../layout/layoutInfo";
import { JOINT_PLOTS, TCP_PLOTS, type PlotSpec } from "../plots/plots";
import { JOINT_COLUMNS, TCP_ROWS } from "../layout/readouts";
import type { Subscription } from "./stream";

/** At most this wide (CSS px) a screen is a phone's: styles/phone.css and
 * styles/responsive.css lay the panel out so. */
export const PHONE_MAX_WIDTH_PX = 700;
/** A phone's frames per second: its tables and open plots redraw at about this rate. */
export const PHONE_RATE_HZ = 10;

const plotFields = (plots: readonly PlotSpec[]) => plots.flatMap((p) => p.series.map((s) => s.field));

/** The header's fields: the state (its badge) and the flags (behind the phone's menu, but small). */
export const HEADER_FIELDS: readonly string[] = ["robot_state", ...FLAG_FIELDS.map((f) => f.name)];

/**
 * The fields each section of the panel shows (by its id), with its plots when they are open.
 * Sections that show no frame field (alarms, events, …) are absent.
 */
export function sectionFields(section: string, plotsOpen: boolean): readonly string[] {
  switch (section) {
    case "joints":
      return [...JOINT_COLUMNS.map((c) => c.field), ...TCP_ROWS.map((r) => r.field), ...(plotsOpen ? plotFields(JOINT_PLOTS) : [])];
    case "tcp":
      return plotsOpen ? plotFields(TCP_PLOTS) : [];
    case "robot3d":
      return ["joint_position"];
    case "io":
      return ["controlbox_di", "controlbox_do", "tool_di", "tool_do", "analog_input", "analog_output", "analog_input_type", "analog_output_type"];
    case "registers":
      return ["bit_output_registers"];
    case "checkout":
      return ["controlbox_di", "controlbox_do", "tool_di", "tool_do", "analog_input", "analog_output"];
    default:
      return [];
  }
}

/**
 * What a panel asks of its stream with `inView` sections on screen and its plots `plotsOpen`:
 * null (every field of every frame) on a wide screen; on a phone (`narrow`) the header's and
 * those sections' fields, sorted and once each, at `PHONE_RATE_HZ`.
 */
export function panelSubscription(narrow: boolean, inView: ReadonlySet<string>, plotsOpen: boolean): Subscription | null {
  if (!narrow) return null;
  const fields = new Set(HEADER_FIELDS);
  for (const section of inView) for (const field of sectionFields(section, plotsOpen)) fields.add(field);
  return { fields: [...fields].sort(), rate_hz: PHONE_RATE_HZ };
}
