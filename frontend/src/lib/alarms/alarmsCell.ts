/**
 * Layer: the cell's alarms at a glance (pure: no React, no DOM, no network).
 *
 * The service sums up every robot's alarms (`AlarmSummary`, `CellAlarmSummary`: GET
 * /api/v1/robots, GET /api/v1/alarms/summary, the stream's hello and status `cell_alarms`); a
 * panel open on one robot shows the others' from it (a mark on the robot switcher, a line in
 * the banner naming the robot) and the fleet page each robot's. Nothing here re-counts alarms:
 * the words are made from the service's counts and its most urgent alarm.
 */
import { alarmStateWords, alarmTitle, isUnacknowledged, type Alarm } from "./alarms";
import type { AlarmSummary, CellAlarmSummary } from "../api/protocol";

type Brief = NonNullable<AlarmSummary["top"]>;

/** Whether a robot has an alarm a person must see (not normal, not shelved, not suppressed). */
export function hasAnnunciated(summary: AlarmSummary | null | undefined): boolean {
  if (summary === null || summary === undefined) return false;
  return (summary.annunciated ?? 0) > 0 || summary.top != null;
}

const RANK = { critical: 0, high: 1, medium: 2, low: 3, advisory: 4 } as const;

function rankOf(summary: AlarmSummary): number {
  return summary.highest_priority !== null ? RANK[summary.highest_priority] : 5;
}

/**
 * The other robots of the cell with an annunciated alarm, most urgent first (then the service's
 * order): the robot switcher marks them, the panel's banner gives each a line.
 */
export function otherRobotAlarms(cell: CellAlarmSummary | null, robot: string): readonly AlarmSummary[] {
  if (cell === null) return [];
  return cell.robots
    .filter((s) => s.robot != null && s.robot !== robot && hasAnnunciated(s))
    .map((s, order) => ({ s, order }))
    .sort((a, b) => rankOf(a.s) - rankOf(b.s) || a.order - b.order)
    .map(({ s }) => s);
}

/** The robots' names with an annunciated alarm → their summary, for the switcher's options. */
export function alarmsByRobot(cell: CellAlarmSummary | null): ReadonlyMap<string, AlarmSummary> {
  const byRobot = new Map<string, AlarmSummary>();
  for (const s of cell?.robots ?? []) if (s.robot != null && hasAnnunciated(s)) byRobot.set(s.robot, s);
  return byRobot;
}

/** The most urgent alarm of a summary in words: "Emergency stop — critical, active, unacknowledged". */
export function briefWords(top: Brief): string {
  // A summary's top alarm is annunciated: never shelved.
  return `${alarmTitle(top)} — ${top.priority}, ${alarmStateWords({ state: top.state, shelved: false })}`;
}

/** "3 alarms (2 unacknowledged)", "1 alarm", "none"; shelved and suppressed ones named after. */
export function summaryCountWords(summary: AlarmSummary): string {
  const annunciated = summary.annunciated ?? 0;
  const parts: string[] = [];
  if (annunciated > 0) {
    const alarms = `${annunciated} alarm${annunciated === 1 ? "" : "s"}`;
    parts.push(summary.unacknowledged > 0 ? `${alarms} (${summary.unacknowledged} unacknowledged)` : alarms);
  }
  if (summary.shelved > 0) parts.push(`${summary.shelved} shelved`);
  if ((summary.suppressed ?? 0) > 0) parts.push(`${summary.suppressed ?? 0} suppressed by design`);
  return parts.length === 0 ? "none" : parts.join(", ");
}

/** The banner's line for another robot: "m0609: Emergency stop — critical, active, unacknowledged · 2 alarms". */
export function otherRobotLine(summary: AlarmSummary): string {
  const robot = summary.robot ?? "?";
  const top = summary.top ?? null;
  const count = summaryCountWords(summary);
  return top !== null ? `${robot}: ${briefWords(top)} · ${count}` : `${robot}: ${count}`;
}

/** Whether the most urgent alarm of a summary waits for an acknowledgement. */
export function topUnacknowledged(summary: AlarmSummary): boolean {
  return summary.top != null && isUnacknowledged(summary.top);
}

/**
 * The alarms "acknowledge all shown" acknowledges: those of the list that are annunciated and
 * unacknowledged (a suppressed or shelved alarm has nothing to acknowledge; the service says
 * "unchanged" for one that was acknowledged meanwhile).
 */
export function acknowledgeable(alarms: readonly Alarm[]): readonly string[] {
  return alarms.filter((a) => !a.shelved && a.state !== "suppressed" && isUnacknowledged(a)).map((a) => a.id);
}

/** A suppressed alarm in words: "suppressed by design: a consequence of Emergency stop". */
export function suppressionWords(alarm: Pick<Alarm, "state" | "suppressed_by" | "suppressed_by_name">): string | null {
  if (alarm.state !== "suppressed") return null;
  const cause = alarm.suppressed_by_name ?? alarm.suppressed_by ?? null;
  return cause !== null ? `suppressed by design: a consequence of ${cause}` : "suppressed by design";
}
