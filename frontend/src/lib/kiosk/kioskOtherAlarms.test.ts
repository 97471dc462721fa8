import { describe, expect, it } from "vitest";
import { concernsKiosk, kioskOtherAlarms } from "./kioskOtherAlarms";
import type { AlarmSummary, CellAlarmSummary } from "../api/protocol";

type Brief = NonNullable<AlarmSummary["top"]>;
type Counts = NonNullable<AlarmSummary["by_priority"]>;

function brief(robot: string, over: Partial<Brief> = {}): Brief {
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

function counts(over: Partial<Counts> = {}): Counts {
  const none = { annunciated: 0, active: 0, unacknowledged: 0 };
  return { critical: none, high: none, medium: none, low: none, ...over };
}

function summary(robot: string, over: Partial<AlarmSummary> = {}): AlarmSummary {
  return { robot, active: 0, annunciated: 0, unacknowledged: 0, shelved: 0, suppressed: 0, highest_priority: null, top: null, by_priority: counts(), ...over };
}

const estopped = (robot: string) =>
  summary(robot, { active: 1, annunciated: 1, unacknowledged: 1, highest_priority: "critical", top: brief(robot), by_priority: counts({ critical: { annunciated: 1, active: 1, unacknowledged: 1 } }) });
/** An e-stop acknowledged and still active: critical, so still shown. */
const estopAcknowledged = (robot: string) =>
  summary(robot, {
    active: 1,
    annunciated: 1,
    highest_priority: "critical",
    top: brief(robot, { state: "active_acknowledged" }),
    by_priority: counts({ critical: { annunciated: 1, active: 1, unacknowledged: 0 } }),
  });
/** A medium alarm acknowledged: nothing for a kiosk. */
const warmAcknowledged = (robot: string) =>
  summary(robot, {
    active: 1,
    annunciated: 1,
    highest_priority: "medium",
    top: brief(robot, { name: "Motor temperature J 3 high", priority: "medium", priority_rank: 2, colour: "yellow", state: "active_acknowledged" }),
    by_priority: counts({ medium: { annunciated: 1, active: 1, unacknowledged: 0 } }),
  });
/** A high alarm nobody acknowledged: shown. */
const doorOpen = (robot: string) =>
  summary(robot, {
    active: 1,
    annunciated: 1,
    unacknowledged: 1,
    highest_priority: "high",
    top: brief(robot, { name: "Cell door open", priority: "high", priority_rank: 1, colour: "orange" }),
    by_priority: counts({ high: { annunciated: 1, active: 1, unacknowledged: 1 } }),
  });

function cell(...robots: AlarmSummary[]): CellAlarmSummary {
  return { annunciated: robots.reduce((n, r) => n + (r.annunciated ?? 0), 0), highest_priority: null, robots, top: null };
}

describe("the kiosk's line of the other robots' alarms", () => {
  it("names another robot's emergency stop, never the kiosk's own robot", () => {
    const lines = kioskOtherAlarms(cell(estopped("m1013"), estopped("m0609")), "m1013");
    expect(lines).toEqual([
      {
        robot: "m0609",
        text: "m0609: Emergency stop — critical, active, unacknowledged · 1 alarm (1 unacknowledged)",
        priority: "critical",
        colour: "red",
        unacknowledged: true,
      },
    ]);
  });

  it("shows critical alarms and unacknowledged ones, not an acknowledged lesser alarm", () => {
    const all = cell(summary("m1013"), warmAcknowledged("a"), doorOpen("b"), estopAcknowledged("c"));
    expect(kioskOtherAlarms(all, "m1013").map((l) => l.robot)).toEqual(["c", "b"]);
    expect(concernsKiosk(warmAcknowledged("a"))).toBe(false);
    expect(concernsKiosk(estopAcknowledged("c"))).toBe(true);
    expect(concernsKiosk(doorOpen("b"))).toBe(true);
  });

  it("leaves out shelved and suppressed alarms (not annunciated) and waits for the robot's name", () => {
    const quiet = summary("b", { active: 2, shelved: 1, suppressed: 1 });
    expect(kioskOtherAlarms(cell(quiet), "a")).toEqual([]);
    expect(kioskOtherAlarms(cell(estopped("b")), null)).toEqual([]);
    expect(kioskOtherAlarms(null, "a")).toEqual([]);
  });

  it("falls back on the most urgent alarm when the service gives no counts per priority", () => {
    expect(concernsKiosk({ ...warmAcknowledged("a"), by_priority: null })).toBe(false);
    expect(concernsKiosk({ ...estopAcknowledged("a"), by_priority: null })).toBe(true);
    expect(concernsKiosk({ ...doorOpen("a"), by_priority: null })).toBe(true);
  });
});
