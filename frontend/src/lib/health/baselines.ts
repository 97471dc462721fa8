/**
 * Layer: pure rules of the baselines' list and of the re-baselining form (no React, no DOM):
 * what a row says (who set it, why, from what), what the form may send, and why the service
 * refused it in words. Re-baselining is an operator's audited action (docs/health.md).
 */
import type { User } from "../api/protocol";
import { roleAtLeast } from "../api/protocol";
import { formatTimestamp } from "../common/dates";
import type { BaselineRecord, BaselineRequest } from "./healthTypes";

/** The form's cycles: what it starts with, and the bounds it accepts. */
export const DEFAULT_BASELINE_CYCLES = 50;
export const MIN_BASELINE_CYCLES = 1;
export const MAX_BASELINE_CYCLES = 100_000;

/** The form's fields as typed, checked: the body to send, or why not (said beside the field). */
export type BaselineCheck = { readonly ok: true; readonly body: BaselineRequest & { readonly cycles: number } } | { readonly ok: false; readonly field: "reason" | "cycles"; readonly reason: string };

export function checkBaselineForm(reason: string, cycles: string): BaselineCheck {
  const why = reason.trim();
  if (why === "") return { ok: false, field: "reason", reason: "say why (a reducer changed, a new program…): the audit keeps it" };
  const n = Number(cycles.trim());
  if (cycles.trim() === "" || !Number.isInteger(n)) return { ok: false, field: "cycles", reason: "the cycles to learn from: a whole number" };
  if (n < MIN_BASELINE_CYCLES || n > MAX_BASELINE_CYCLES) {
    return { ok: false, field: "cycles", reason: `between ${MIN_BASELINE_CYCLES} and ${MAX_BASELINE_CYCLES.toLocaleString("en-US")} cycles` };
  }
  return { ok: true, body: { reason: why, cycles: n } };
}

/** The longest period a baseline is learned from (the service's bound). */
export const MAX_BASELINE_PERIOD_DAYS = 7;

/** A recorded period's form, checked: from and to as typed in the page's date-time fields
 * (no offset: the service reads them in the plant's time zone, as the pages show times). */
export type PeriodCheck = { readonly ok: true; readonly body: BaselineRequest & { readonly from: string; readonly to: string } } | { readonly ok: false; readonly field: "reason" | "from" | "to"; readonly reason: string };

export function checkPeriodBaselineForm(reason: string, from: string, to: string): PeriodCheck {
  const why = reason.trim();
  if (why === "") return { ok: false, field: "reason", reason: "say why (a reducer changed, a new program…): the audit keeps it" };
  const start = from.trim();
  const end = to.trim();
  if (start === "" || Number.isNaN(Date.parse(start))) return { ok: false, field: "from", reason: "the period's start: a date and time" };
  if (end === "" || Number.isNaN(Date.parse(end))) return { ok: false, field: "to", reason: "the period's end: a date and time" };
  const spanMs = Date.parse(end) - Date.parse(start);
  if (spanMs <= 0) return { ok: false, field: "to", reason: "the period must end after it starts" };
  if (spanMs > MAX_BASELINE_PERIOD_DAYS * 86_400_000) return { ok: false, field: "to", reason: `a period of at most ${MAX_BASELINE_PERIOD_DAYS} days` };
  return { ok: true, body: { reason: why, from: start, to: end } };
}

/** Why the form is not offered to this person (null: it is). */
export function baselineBlockedReason(user: User | null): string | null {
  if (user === null) return "Log in as an operator to set a new baseline.";
  if (!roleAtLeast(user, "operator")) return `Setting a baseline needs an operator; ${user.name} is a ${user.role}.`;
  return null;
}

/** The service's refusal of a re-baselining, in words a person acts on. */
export function baselineRefusalWords(status: number, reason: string): string {
  switch (status) {
    case 401:
      return `Not logged in any more: log in again (${reason}).`;
    case 403:
      return `Refused: setting a baseline needs an operator (${reason}).`;
    case 409:
      return `Refused: ${reason}`;
    case 422:
      return `Refused, the form is not right: ${reason}`;
    default:
      return `The service did not set the baseline: ${reason}`;
  }
}

/** One baseline of the list, in words. */
export interface BaselineRow {
  readonly id: number;
  readonly reason: string;
  readonly by: string;
  readonly started: string;
  readonly finished: string;
  readonly learnedFrom: string;
  readonly inUse: boolean;
  readonly learning: boolean;
}

function learnedFrom(b: BaselineRecord): string {
  if (b.learning) {
    const of = typeof b.target_cycles === "number" ? ` of ${b.target_cycles}` : "";
    return `${b.cycles ?? 0}${of} cycles so far`;
  }
  if (typeof b.cycles === "number") return `${b.cycles} cycle${b.cycles === 1 ? "" : "s"}`;
  if (typeof b.target_cycles === "number") return `${b.target_cycles} cycles`;
  return "—";
}

/** The baselines, newest first (the one being learned on top), the one in use marked. */
export function baselineRows(baselines: readonly BaselineRecord[], zone?: string): readonly BaselineRow[] {
  return [...baselines]
    .sort((a, b) => Number(b.learning) - Number(a.learning) || b.created_at - a.created_at || b.id - a.id)
    .map((b) => ({
      id: b.id,
      reason: b.reason,
      by: b.created_by,
      started: formatTimestamp(b.created_at, zone),
      finished: b.learning ? "learning…" : typeof b.learned_to === "number" ? formatTimestamp(b.learned_to, zone) : "—",
      learnedFrom: learnedFrom(b),
      inUse: b.active,
      learning: b.learning,
    }));
}
