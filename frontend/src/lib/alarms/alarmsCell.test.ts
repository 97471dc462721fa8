import { describe, expect, it } from "vitest";
import type { Alarm } from "./alarms";
import { acknowledgeable, alarmsByRobot, hasAnnunciated, otherRobotAlarms, otherRobotLine, summaryCountWords, suppressionWords, topUnacknowledged } from "./alarmsCell";
import { brief, cell, stopped, summary } from "./alarmTestSupport";

const warm = (robot: string) =>
  summary(robot, { active: 1, annunciated: 1, highest_priority: "medium", top: brief(robot, { name: "Motor temperature J 3 high", priority: "medium", priority_rank: 2, colour: "yellow", state: "active_acknowledged" }) });


describe("the other robots' alarms", () => {
  it("lists the other robots with an annunciated alarm, most urgent first, never the robot shown", () => {
    const all = cell(summary("a"), warm("b"), stopped("c"), stopped("d"));
    expect(otherRobotAlarms(all, "a").map((s) => s.robot)).toEqual(["c", "d", "b"]);
    expect(otherRobotAlarms(all, "c").map((s) => s.robot)).toEqual(["d", "b"]);
    expect(otherRobotAlarms(null, "a")).toEqual([]);
  });

  it("does not count suppressed or shelved alarms as annunciated", () => {
    const suppressedOnly = summary("b", { active: 1, suppressed: 1 });
    const shelvedOnly = summary("c", { active: 1, shelved: 1 });
    expect(hasAnnunciated(suppressedOnly)).toBe(false);
    expect(otherRobotAlarms(cell(suppressedOnly, shelvedOnly), "a")).toEqual([]);
    expect([...alarmsByRobot(cell(suppressedOnly, stopped("d"))).keys()]).toEqual(["d"]);
  });

  it("names the robot, its most urgent alarm in words and the counts", () => {
    expect(otherRobotLine(stopped("m0609"))).toBe("m0609: Emergency stop — critical, active, unacknowledged · 1 alarm (1 unacknowledged)");
    expect(otherRobotLine(warm("b"))).toBe("b: Motor temperature J 3 high — medium, active, acknowledged · 1 alarm");
    expect(topUnacknowledged(stopped("a"))).toBe(true);
    expect(topUnacknowledged(warm("a"))).toBe(false);
    expect(summaryCountWords(summary("a"))).toBe("none");
    expect(summaryCountWords(summary("a", { annunciated: 3, unacknowledged: 2, shelved: 1, suppressed: 2 }))).toBe("3 alarms (2 unacknowledged), 1 shelved, 2 suppressed by design");
  });
});

function alarm(key: string, state: Alarm["state"], over: Partial<Alarm> = {}): Alarm {
  return { id: `a:${key}`, state, shelved: false, suppressed_by: null, suppressed_by_name: null, ...over } as Alarm;
}

describe("acknowledging what the list shows", () => {
  it("acknowledges the unacknowledged alarms, not the suppressed, shelved or acknowledged ones", () => {
    const list = [
      alarm("emergency_stop", "returned_unacknowledged"),
      alarm("safe_off", "suppressed", { suppressed_by: "a:emergency_stop", suppressed_by_name: "Emergency stop" }),
      alarm("protective_stop", "active_unacknowledged"),
      alarm("packet_loss", "active_unacknowledged", { shelved: true }),
      alarm("motor_temperature.2", "active_acknowledged"),
    ];
    expect(acknowledgeable(list)).toEqual(["a:emergency_stop", "a:protective_stop"]);
  });

  it("says what a suppressed alarm is a consequence of", () => {
    expect(suppressionWords(alarm("safe_off", "suppressed", { suppressed_by: "a:emergency_stop", suppressed_by_name: "Emergency stop" }))).toBe(
      "suppressed by design: a consequence of Emergency stop",
    );
    expect(suppressionWords(alarm("safe_off", "suppressed", { suppressed_by: "a:emergency_stop" }))).toBe("suppressed by design: a consequence of a:emergency_stop");
    expect(suppressionWords(alarm("safe_off", "active_unacknowledged"))).toBeNull();
  });
});
