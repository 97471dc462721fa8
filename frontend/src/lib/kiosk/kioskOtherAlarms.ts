/**
 * Layer: the kiosk's line of the other robots' alarms (pure: no React, no DOM, no network).
 *
 * A kiosk shows one robot, but an emergency stop of its neighbour concerns whoever stands there
 * too: each other robot of the cell with a critical alarm, or one nobody acknowledged yet, gets a
 * line naming the robot and its most urgent alarm (from the stream's `cell_alarms`, which every
 * status brings: the service's own counts, never re-counted here). Shelved and suppressed alarms
 * are not annunciated and give no line.
 */
import { otherRobotAlarms, otherRobotLine, topUnacknowledged } from "../alarms/alarmsCell";
import type { AlarmSummary, CellAlarmSummary } from "../api/protocol";

export interface KioskOtherLine {
  readonly robot: string;
  /** "m0609: Emergency stop — critical, active, unacknowledged · 1 alarm (1 unacknowledged)" */
  readonly text: string;
  readonly priority: string;
  /** The most urgent alarm's pendant colour. */
  readonly colour: string;
  readonly unacknowledged: boolean;
}

/** Whether another robot's alarms belong on a kiosk: a critical one, or one unacknowledged. */
export function concernsKiosk(summary: AlarmSummary): boolean {
  const counts = summary.by_priority;
  if (counts !== null && counts !== undefined) {
    const critical = counts.critical?.annunciated ?? 0;
    const unacknowledged = Object.values(counts).reduce((n, c) => n + (c?.unacknowledged ?? 0), 0);
    return critical > 0 || unacknowledged > 0;
  }
  // A service that gives no counts per priority: its most urgent alarm decides.
  return summary.highest_priority === "critical" || topUnacknowledged(summary);
}

/** The lines of the other robots' alarms for the kiosk of `robot`, most urgent first. */
export function kioskOtherAlarms(cell: CellAlarmSummary | null, robot: string | null): readonly KioskOtherLine[] {
  if (robot === null) return [];
  return otherRobotAlarms(cell, robot)
    .filter(concernsKiosk)
    .map((summary) => ({
      robot: summary.robot ?? "?",
      text: otherRobotLine(summary),
      priority: summary.highest_priority ?? "",
      colour: summary.top?.colour ?? "",
      unacknowledged: topUnacknowledged(summary),
    }));
}
