import { describe, expect, it } from "vitest";
import {
  alarmPaint,
  alarmsFromHello,
  alarmStateWords,
  alarmTitle,
  applyAlarm,
  bannerView,
  compareAlarms,
  countWords,
  cueTone,
  mute,
  NO_MUTE,
  sounding,
  PRIORITY_COLOUR,
  tagLabel,
} from "./alarms";
import { alarm } from "./alarmTestSupport";

const estop = alarm("emergency_stop", { name: "Emergency stop", priority: "critical", colour: "red", changed_at: 90 });
const loss = alarm("packet_loss", { name: "Packet loss", priority: "medium", changed_at: 120 });
const temp = alarm("motor_temperature.2", {
  name: "Motor temperature J 3 high",
  priority: "medium",
  label: "J 3",
  tag: "wrist",
  changed_at: 130,
});

describe("alarm order and the banner's choice", () => {
  it("orders by priority, then the newest change, active before returned, shelved last", () => {
    const returnedCritical = alarm("safe_off", { priority: "critical", state: "returned_unacknowledged", changed_at: 200 });
    const shelvedCritical = alarm("x", { priority: "critical", shelved: true, changed_at: 300 });
    const sorted = [loss, shelvedCritical, temp, returnedCritical, estop].sort(compareAlarms).map((a) => a.key);
    expect(sorted).toEqual(["emergency_stop", "motor_temperature.2", "packet_loss", "safe_off", "x"]);
  });

  it("shows the most urgent active alarm and counts the others, shelved ones left out", () => {
    const shelved = alarm("user.door", { priority: "critical", shelved: true });
    const view = bannerView([loss, temp, shelved, estop]);
    expect(view.top?.key).toBe("emergency_stop");
    expect(view).toMatchObject({ count: 3, active: 3, unacknowledged: 3, shelved: 1 });
    expect(countWords(view)).toBe("3 alarms (3 unacknowledged)");
  });

  it("prefers an active alarm of lower priority to a returned one of higher priority", () => {
    const returned = alarm("emergency_stop", { priority: "critical", state: "returned_unacknowledged" });
    expect(bannerView([returned, loss]).top?.key).toBe("packet_loss");
    // Only returned, unacknowledged ones left: the banner still asks for an acknowledgement.
    const view = bannerView([returned]);
    expect(view.top?.key).toBe("emergency_stop");
    expect(view.active).toBe(0);
  });

  it("hides the banner when nothing needs a person", () => {
    const acked = alarm("emergency_stop", { state: "active_acknowledged" });
    expect(bannerView([]).top).toBeNull();
    expect(bannerView([alarm("a", { shelved: true })]).top).toBeNull();
    const view = bannerView([acked]);
    expect(view.top?.key).toBe("emergency_stop");
    expect(view.unacknowledged).toBe(0);
    expect(countWords(view)).toBe("1 alarm");
  });
});

describe("alarm list from the stream", () => {
  it("starts from the hello's list, sorted, without normal alarms", () => {
    const list = alarmsFromHello([loss, alarm("gone", { state: "normal" }), estop]);
    expect(list.map((a) => a.key)).toEqual(["emergency_stop", "packet_loss"]);
    expect(alarmsFromHello(undefined)).toEqual([]);
  });

  it("follows transitions: activated, acknowledged, cleared; a repeated event changes nothing", () => {
    let list = alarmsFromHello([loss]);
    list = applyAlarm(list, estop);
    expect(list.map((a) => a.key)).toEqual(["emergency_stop", "packet_loss"]);
    const acked = { ...estop, state: "active_acknowledged" as const, acknowledged: true, changed_at: 150 };
    list = applyAlarm(list, acked);
    expect(list[0]?.state).toBe("active_acknowledged");
    expect(applyAlarm(list, acked)).toBe(list);
    list = applyAlarm(list, { ...acked, state: "normal", active: false, changed_at: 160 });
    expect(list.map((a) => a.key)).toEqual(["packet_loss"]);
    // A normal alarm that was not in the list: nothing to do.
    expect(applyAlarm(list, alarm("other", { state: "normal" }))).toBe(list);
    // A shelved alarm stays listed (to unshelve it) even when its condition went.
    list = applyAlarm(list, alarm("door", { state: "normal", active: false, shelved: true }));
    expect(list.map((a) => a.key)).toEqual(["packet_loss", "door"]);
  });
});

describe("the audible cue", () => {
  it("sounds for unacknowledged alarms until muted, and again for a new one", () => {
    const list = [estop, loss];
    expect(sounding(list, NO_MUTE).map((a) => a.key)).toEqual(["emergency_stop", "packet_loss"]);
    const muted = mute(list);
    expect(sounding(list, muted)).toEqual([]);
    // A new alarm sounds through the mute; the muted ones stay silent.
    expect(sounding([...list, temp], muted).map((a) => a.key)).toEqual(["motor_temperature.2"]);
    // The same alarm activated again (a new activation time) sounds again.
    expect(sounding([{ ...estop, activated_at: 500 }], muted).map((a) => a.key)).toEqual(["emergency_stop"]);
  });

  it("is silent for acknowledged and shelved alarms", () => {
    const acked = alarm("a", { state: "active_acknowledged" });
    const shelved = alarm("b", { shelved: true });
    expect(sounding([acked, shelved], NO_MUTE)).toEqual([]);
  });

  it("is more urgent for a higher priority", () => {
    expect(cueTone("critical").period_ms).toBeLessThan(cueTone("high").period_ms);
    expect(cueTone("high").period_ms).toBeLessThan(cueTone("medium").period_ms);
    expect(cueTone("critical").beeps).toBeGreaterThan(cueTone("low").beeps);
  });
});

describe("alarm words", () => {
  it("joins a label and a tag name", () => {
    expect(tagLabel("DO 3", "gripper close")).toBe("DO 3 — gripper close");
    expect(tagLabel("DO 3", null)).toBe("DO 3");
    expect(tagLabel(null, "gripper")).toBe("gripper");
    expect(tagLabel(null, "")).toBe("");
  });

  it("names the point once: the tag beside a name that has the label already", () => {
    expect(alarmTitle(temp)).toBe("Motor temperature J 3 high (wrist)");
    expect(alarmTitle(estop)).toBe("Emergency stop");
    expect(alarmTitle({ name: "Door open", label: "DI 4", tag: "door" })).toBe("Door open · DI 4 — door");
  });

  it("says the ISA-18.2 state in words", () => {
    expect(alarmStateWords({ state: "returned_unacknowledged", shelved: false })).toBe("returned to normal, unacknowledged");
    expect(alarmStateWords({ state: "active_acknowledged", shelved: true })).toBe("active, acknowledged, shelved");
  });
});

describe("advisory alarms (robot health's maintenance advice)", () => {
  const advice = alarm("health.3", { name: "Maintenance advised: J 3", priority: "advisory", priority_rank: 4, colour: "grey", kind: "health", changed_at: 300 });

  it("come after every other priority, newer or not, and are chosen by the banner only when alone", () => {
    const low = alarm("user.door", { priority: "low", priority_rank: 3, changed_at: 10 });
    expect(alarmsFromHello([advice, low, estop]).map((a) => a.key)).toEqual(["emergency_stop", "user.door", "health.3"]);
    expect(bannerView([advice, low]).top?.key).toBe("user.door");
    expect(bannerView([advice]).top?.key).toBe("health.3");
  });

  it("are seen, never heard", () => {
    expect(sounding([advice], NO_MUTE)).toEqual([]);
    expect(sounding([advice, loss], NO_MUTE).map((a) => a.key)).toEqual(["packet_loss"]);
  });

  it("are painted in a grey of their own, with white text on it", () => {
    expect(PRIORITY_COLOUR.advisory).toBe("grey");
    expect(alarmPaint("grey")).toEqual({ background: "#4a5561", text: "#ffffff" });
    expect(alarmPaint("grey")).not.toEqual(alarmPaint("no such colour"));
  });
});
