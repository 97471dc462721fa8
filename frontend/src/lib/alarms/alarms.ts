/**
 * Layer: pure alarm rules of the panel and the kiosk (no React, no DOM, no network).
 *
 * The service evaluates the alarms (docs/api.md "Alarms"); the browser only keeps the robot's
 * current alarms as the stream tells them — the list of the `hello` message, then one `alarm`
 * event per change — orders them, chooses what the banner shows, and decides whether the
 * audible cue sounds. States, priorities and colours are the service's own (`Alarm.state`,
 * `Alarm.priority_rank`, `Alarm.colour`); nothing here re-evaluates a condition.
 */
import type { components } from "../../generated/api";
import { paintOf, type Paint } from "../layout/stateBadge";

type Schemas = components["schemas"];
export type Alarm = Schemas["Alarm"];
export type AlarmState = Alarm["state"];
export type AlarmPriority = Alarm["priority"];
export type AlarmHistoryRow = Schemas["AlarmHistoryRow"];

/** Every priority, most urgent first (the history filter offers them in this order). */
export const ALARM_PRIORITIES = ["critical", "high", "medium", "low", "advisory"] as const satisfies readonly AlarmPriority[];

/** The priority's colour (teach-pendant semantics, as the service gives `Alarm.colour`). */
export const PRIORITY_COLOUR: Readonly<Record<AlarmPriority, string>> = {
  critical: "red",
  high: "orange",
  medium: "yellow",
  low: "blue",
  advisory: "grey",
};

const ORANGE: Paint = { background: "#e8710a", text: "#111111" };
/**
 * Advisory (robot health's maintenance advice): a slate grey of its own, apart from the
 * neutral grey of an unknown state (which says "no data"), white text on it at 6:1.
 */
const GREY: Paint = { background: "#4a5561", text: "#ffffff" };

/** How an alarm colour is painted: the pendant's paints, plus the orange of a high priority and the grey of an advisory. */
export function alarmPaint(colour: string): Paint {
  if (colour === "orange") return ORANGE;
  if (colour === "grey") return GREY;
  return paintOf(colour);
}

/**
 * Whether an alarm needs a person: its condition is there or nobody acknowledged it yet. An
 * alarm suppressed by design (a consequence of the alarm `suppressed_by` names) does not.
 */
export function isAnnunciated(alarm: Alarm): boolean {
  return alarm.state !== "normal" && alarm.state !== "suppressed" && !alarm.shelved;
}

export function isUnacknowledged(alarm: Pick<Alarm, "state">): boolean {
  return alarm.state === "active_unacknowledged" || alarm.state === "returned_unacknowledged";
}

/**
 * The order of the list and of the banner's choice: annunciated before shelved, active before
 * returned, then by priority, then the newest change first (the service's own order within the
 * same priority, docs/api.md).
 */
export function compareAlarms(a: Alarm, b: Alarm): number {
  const shelved = Number(a.shelved) - Number(b.shelved);
  if (shelved !== 0) return shelved;
  const active = Number(b.active) - Number(a.active);
  if (active !== 0) return active;
  if (a.priority_rank !== b.priority_rank) return a.priority_rank - b.priority_rank;
  const changed = (b.changed_at ?? 0) - (a.changed_at ?? 0);
  if (changed !== 0) return changed;
  return a.id < b.id ? -1 : a.id > b.id ? 1 : 0;
}

/** Whether the alarm belongs in the current list (a normal alarm is kept only while shelved). */
function isCurrent(alarm: Alarm): boolean {
  return alarm.state !== "normal" || alarm.shelved;
}

/** The current alarms from a stream's `hello` (a new list: the hello replaces everything). */
export function alarmsFromHello(alarms: readonly Alarm[] | undefined): readonly Alarm[] {
  return (alarms ?? []).filter(isCurrent).sort(compareAlarms);
}

/**
 * The current alarms after one `alarm` event: the alarm's record replaces the one with its id;
 * one back to normal (and not shelved) leaves the list. Returns the same array when the event
 * changes nothing the list shows (a repeated event), so a view need not redraw.
 */
export function applyAlarm(current: readonly Alarm[], alarm: Alarm): readonly Alarm[] {
  const index = current.findIndex((a) => a.id === alarm.id);
  if (!isCurrent(alarm)) return index < 0 ? current : current.filter((_, i) => i !== index);
  const before = index < 0 ? undefined : current[index];
  if (before !== undefined && sameShown(before, alarm)) return current;
  const next = index < 0 ? [...current, alarm] : current.map((a, i) => (i === index ? alarm : a));
  return next.sort(compareAlarms);
}

function sameShown(a: Alarm, b: Alarm): boolean {
  return (
    a.state === b.state &&
    a.shelved === b.shelved &&
    a.changed_at === b.changed_at &&
    a.tag === b.tag &&
    a.message === b.message &&
    a.shelved_until === b.shelved_until
  );
}

export interface BannerView {
  /** The most urgent annunciated alarm (active before returned), null: the banner is hidden. */
  readonly top: Alarm | null;
  /** Annunciated alarms (not normal, not shelved), the top one included. */
  readonly count: number;
  readonly active: number;
  readonly unacknowledged: number;
  readonly shelved: number;
}

/** What the alarm banner shows for the current alarms (sorted by `compareAlarms` or not). */
export function bannerView(alarms: readonly Alarm[]): BannerView {
  let top: Alarm | null = null;
  let count = 0;
  let active = 0;
  let unacknowledged = 0;
  let shelved = 0;
  for (const alarm of alarms) {
    if (alarm.shelved) {
      shelved++;
      continue;
    }
    if (alarm.state === "normal" || alarm.state === "suppressed") continue;
    count++;
    if (alarm.active) active++;
    if (isUnacknowledged(alarm)) unacknowledged++;
    if (top === null || compareAlarms(alarm, top) < 0) top = alarm;
  }
  return { top, count, active, unacknowledged, shelved };
}

/** "DO 3 — gripper close", "J 3 — wrist", "DO 3", or the tag alone. */
export function tagLabel(label: string | null | undefined, tag: string | null | undefined): string {
  const l = label ?? "";
  const t = tag ?? "";
  if (l !== "" && t !== "") return `${l} — ${t}`;
  return l !== "" ? l : t;
}

/** An alarm's title for a person: its name, and the point it watches with its tag name. */
export function alarmTitle(alarm: Pick<Alarm, "name" | "label" | "tag">): string {
  const point = tagLabel(alarm.label, alarm.tag);
  if (point === "" || alarm.name.includes(point)) return alarm.name;
  // The name often carries the label already ("Motor temperature J 3 high"): add the tag only.
  if (alarm.label !== null && alarm.name.includes(alarm.label) && alarm.tag !== null && alarm.tag !== "") {
    return `${alarm.name} (${alarm.tag})`;
  }
  return `${alarm.name} · ${point}`;
}

const STATE_WORDS: Readonly<Record<AlarmState, string>> = {
  normal: "normal",
  active_unacknowledged: "active, unacknowledged",
  active_acknowledged: "active, acknowledged",
  returned_unacknowledged: "returned to normal, unacknowledged",
  suppressed: "active, suppressed by design",
};

export function alarmStateWords(alarm: Pick<Alarm, "state" | "shelved">): string {
  const words = STATE_WORDS[alarm.state];
  return alarm.shelved ? `${words}, shelved` : words;
}

/** The banner's count in words: "1 alarm", "3 alarms (2 unacknowledged)". */
export function countWords(view: BannerView): string {
  const alarms = `${view.count} alarm${view.count === 1 ? "" : "s"}`;
  return view.unacknowledged > 0 ? `${alarms} (${view.unacknowledged} unacknowledged)` : alarms;
}

/**
 * The audible cue: it sounds while an annunciated alarm is unacknowledged, until the operator
 * mutes it; a mute silences the alarms unacknowledged at that moment, and an alarm that comes
 * (or comes again) after it sounds again. Pure: the caller keeps the `Mute` and plays the tone.
 */
export interface Mute {
  /** Alarm id → its `activated_at` when muted (a new activation of the same alarm sounds again). */
  readonly silenced: ReadonlyMap<string, number | null>;
}

export const NO_MUTE: Mute = { silenced: new Map() };

export function mute(alarms: readonly Alarm[]): Mute {
  const silenced = new Map<string, number | null>();
  for (const alarm of alarms) if (isAnnunciated(alarm) && isUnacknowledged(alarm)) silenced.set(alarm.id, alarm.activated_at);
  return { silenced };
}

/** The alarms the cue sounds for now (most urgent first); empty: silent. */
export function sounding(alarms: readonly Alarm[], muted: Mute): readonly Alarm[] {
  return alarms
    .filter((a) => isAnnunciated(a) && isUnacknowledged(a))
    .filter((a) => a.priority !== "advisory") // robot health's maintenance advice: seen, not heard
    .filter((a) => !muted.silenced.has(a.id) || muted.silenced.get(a.id) !== a.activated_at)
    .sort(compareAlarms);
}

/** Tone of the cue by the most urgent sounding priority: pitch, beeps per burst, pause between. */
export interface CueTone {
  readonly frequency_hz: number;
  readonly beeps: number;
  readonly period_ms: number;
}

export function cueTone(priority: AlarmPriority): CueTone {
  switch (priority) {
    case "critical":
      return { frequency_hz: 1000, beeps: 3, period_ms: 1500 };
    case "high":
      return { frequency_hz: 880, beeps: 2, period_ms: 2500 };
    case "medium":
      return { frequency_hz: 660, beeps: 1, period_ms: 4000 };
    case "low":
      return { frequency_hz: 520, beeps: 1, period_ms: 8000 };
    case "advisory": // never sounding (see sounding); a tone for completeness
      return { frequency_hz: 440, beeps: 1, period_ms: 16000 };
  }
}

/** Shelving durations a panel offers, s and in words (each alarm gets those within its maximum). */
export const SHELVE_CHOICES_S: readonly (readonly [number, string])[] = [
  [15 * 60, "15 min"],
  [60 * 60, "1 h"],
  [4 * 3600, "4 h"],
  [8 * 3600, "8 h"],
];

function durationWords(seconds: number): string {
  if (seconds >= 3600 && seconds % 3600 === 0) return `${seconds / 3600} h`;
  if (seconds >= 60 && seconds % 60 === 0) return `${seconds / 60} min`;
  return `${seconds} s`;
}

/**
 * The durations this alarm may be shelved for, shortest first: those of `SHELVE_CHOICES_S` within
 * its `shelve_max_s` (its priority's longest, ISA-18.2 §11.4.3), or that maximum alone when it is
 * shorter than them all; none for an alarm that is never shelved (a safety stop, a critical alarm:
 * `shelve_max_s` null). A service that does not say (no `shelve_max_s`) gets every choice: it
 * refuses what it does not allow.
 */
export function shelveChoices(alarm: Pick<Alarm, "shelve_max_s">): readonly (readonly [number, string])[] {
  const longest = alarm.shelve_max_s;
  if (longest === undefined) return SHELVE_CHOICES_S;
  if (longest === null) return [];
  const fitting = SHELVE_CHOICES_S.filter(([s]) => s <= longest);
  return fitting.length > 0 ? fitting : [[longest, durationWords(longest)]];
}

/** Why this alarm is never shelved (the service's words), or null when it may be. */
export function shelveRefusal(alarm: Pick<Alarm, "shelve_max_s" | "shelve_refusal">): string | null {
  if (alarm.shelve_max_s !== null) return null;
  return alarm.shelve_refusal ?? "this alarm cannot be shelved";
}

/** The duration a shelving form starts with: 1 h where allowed, else the longest allowed. */
export function defaultShelveChoice(choices: readonly (readonly [number, string])[]): number | null {
  if (choices.some(([s]) => s === 3600)) return 3600;
  return choices[choices.length - 1]?.[0] ?? null;
}
