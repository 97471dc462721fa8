/**
 * Layer: pure checks the panel makes before it asks to confirm a write (no React, no DOM).
 *
 * The service validates every write again (docs/api.md, "Writing"); checking here first means a
 * person sees the refusal while typing, not after confirming. Numbers may be typed with a
 * decimal comma. Must not import React or any component.
 */
import type { AnalogRange, Frame } from "../../generated/layout";
import { LAYOUT } from "../../generated/layout";

export type NumberCheck = { readonly ok: true; readonly value: number } | { readonly ok: false; readonly reason: string };

/** One optional sign, digits, and at most one decimal separator (point or comma). */
const DECIMAL = /^[+-]?(\d+([.,]\d*)?|[.,]\d+)$/;

/**
 * A number as a person types it: "12.5", "12,5", " -3 ", ",5". Thousands separators and
 * exponents are refused rather than guessed ("1,234.5" could mean two things).
 */
export function parseDecimal(text: string): NumberCheck {
  const trimmed = text.trim().replace(/^\u2212/, "-");
  if (trimmed === "") return { ok: false, reason: "enter a number" };
  if (!DECIMAL.test(trimmed)) return { ok: false, reason: `"${text.trim()}" is not a number` };
  const value = Number(trimmed.replace(",", "."));
  if (!Number.isFinite(value)) return { ok: false, reason: `"${text.trim()}" is not a number` };
  return { ok: true, value };
}

/** A setpoint typed for an analog output of the given range: parsed, then within the range. */
export function checkSetpoint(text: string, range: AnalogRange | null): NumberCheck {
  const parsed = parseDecimal(text);
  if (!parsed.ok || range === null) return parsed;
  if (parsed.value < range.low || parsed.value > range.high) {
    return { ok: false, reason: `out of range: ${range.low}–${range.high} ${range.unit}` };
  }
  return parsed;
}

function stateLabel(name: string): string {
  return LAYOUT.robot_states.find((s) => s.name === name)?.label ?? name;
}

/**
 * The warning a write's confirmation carries while the robot is stopped for safety (an
 * emergency stop or a protective stop); null when it is not. The write may still be wanted
 * (e.g. switching a lamp), so it is a warning, not a refusal.
 */
export function stopWarning(frame: Frame | null): string | null {
  if (frame === null) return null;
  if (frame.emergency_stopped || frame.robot_state_name === "EMERGENCY_STOP") {
    return `The robot is in ${stateLabel("EMERGENCY_STOP").toLowerCase()}: check the cell before changing its outputs.`;
  }
  if (frame.safety_stopped || frame.robot_state_name === "INTERRUPTED") {
    return `The robot is in ${stateLabel("INTERRUPTED").toLowerCase()}: check the cell before changing its outputs.`;
  }
  return null;
}
