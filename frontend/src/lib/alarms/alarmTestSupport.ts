/** Alarm records as the service sends them (docs/api.md "Alarms"), for the alarm tests and the live store's. */
import type { AlarmSummary, CellAlarmSummary } from "../api/protocol";
import type { Alarm } from "./alarms";

const PRIORITY_RANK = { critical: 0, high: 1, medium: 2, low: 3, advisory: 4 } as const;

/** An alarm record of robot "left" as the service sends it. */
export function alarm(key: string, over: Partial<Alarm> = {}): Alarm {
  const priority = over.priority ?? "medium";
  const state = over.state ?? "active_unacknowledged";
  return {
    id: `left:${key}`,
    robot: "left",
    key,
    name: key,
    description: "",
    priority,
    priority_rank: PRIORITY_RANK[priority],
    colour: "yellow",
    kind: "state",
    element: null,
    label: null,
    tag: null,
    unit: "",
    high: null,
    low: null,
    state,
    active: state === "active_unacknowledged" || state === "active_acknowledged",
    acknowledged: state === "normal" || state === "active_acknowledged",
    shelved: false,
    changed_at: 100,
    activated_at: 100,
    cleared_at: null,
    acknowledged_at: null,
    acknowledged_by: null,
    ack_comment: null,
    shelved_until: null,
    shelved_by: null,
    shelve_reason: null,
    value: null,
    message: null,
    ...over,
  };
}

type Brief = NonNullable<AlarmSummary["top"]>;

/** A robot's top alarm in a cell summary: an unacknowledged emergency stop unless told. */
export function brief(robot: string, over: Partial<Brief> = {}): Brief {
  return {
    id: `${robot}:emergency_stop`,
    key: "emergency_stop",
    robot,
    name: "Emergency stop",
    label: null,
    tag: null,
    message: null,
    priority: "critical",
    priority_rank: 0,
    colour: "red",
    state: "active_unacknowledged",
    active: true,
    activated_at: 1,
    changed_at: 1,
    ...over,
  };
}

/** One robot's alarm summary: no alarm unless told. */
export function summary(robot: string, over: Partial<AlarmSummary> = {}): AlarmSummary {
  return { robot, active: 0, annunciated: 0, unacknowledged: 0, shelved: 0, suppressed: 0, highest_priority: null, top: null, ...over };
}

/** A robot in an unacknowledged emergency stop. */
export const stopped = (robot: string): AlarmSummary =>
  summary(robot, { active: 1, annunciated: 1, unacknowledged: 1, highest_priority: "critical", top: brief(robot) });

/** The cell's summary of these robots. */
export function cell(...robots: AlarmSummary[]): CellAlarmSummary {
  return { annunciated: robots.reduce((n, r) => n + (r.annunciated ?? 0), 0), highest_priority: null, robots, top: null };
}
