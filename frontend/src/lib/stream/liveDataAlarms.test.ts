// The live store's alarms (lib/stream/liveData.ts): the robot's list from the hello and its alarm
// events, the session, and the cell's summary from the hello and each status. The alarm rules it
// applies are lib/alarms/'s, tested there.
import { describe, expect, it } from "vitest";
import { bannerView } from "../alarms/alarms";
import { otherRobotAlarms } from "../alarms/alarmsCell";
import { alarm, cell, stopped, summary } from "../alarms/alarmTestSupport";
import type { ConnectionStatus, ServerMessage } from "../api/protocol";
import { LiveData } from "./liveData";

const connection = { state: "connected", reason: null, stale: false, rpi_ms: 10 } as unknown as ConnectionStatus;
const estop = alarm("emergency_stop", { name: "Emergency stop", priority: "critical", colour: "red", changed_at: 90 });
const loss = alarm("packet_loss", { name: "Packet loss", priority: "medium", changed_at: 120 });

describe("the live store's alarms", () => {
  it("keeps the robot's alarms: the hello's, then alarm events, and the session", () => {
    const live = new LiveData([], { now: () => 0 });
    const hello = {
      type: "hello",
      robot: "left",
      layout_version: 1,
      connection,
      control: { holder: null },
      rate_hz: null,
      session: "s-1",
      alarms: [loss],
    } as ServerMessage;
    live.handle(hello);
    expect(live.getSnapshot().alarms.map((a) => a.key)).toEqual(["packet_loss"]);
    expect(live.getSnapshot().session).toBe("s-1");
    live.handle({ type: "event", event: { kind: "alarm", time: 1, robot: "left", transition: "activated", alarm: estop } } as ServerMessage);
    expect(live.getSnapshot().alarms.map((a) => a.key)).toEqual(["emergency_stop", "packet_loss"]);
    expect(bannerView(live.getSnapshot().alarms).top?.id).toBe("left:emergency_stop");
    // A new socket's hello replaces the list (what changed while away is in it).
    live.handle({ ...hello, alarms: [] } as ServerMessage);
    expect(live.getSnapshot().alarms).toEqual([]);
  });

  it("keeps the cell's alarms from the hello and each status, and keeps the last when a status has none", () => {
    const live = new LiveData([], { now: () => 0 });
    expect(live.getSnapshot().cellAlarms).toBeNull();
    live.handle({ type: "hello", robot: "a", layout_version: 1, connection, control: { holder: null }, rate_hz: null, alarms: [], cell_alarms: cell(summary("a"), summary("b")) } as ServerMessage);
    expect(otherRobotAlarms(live.getSnapshot().cellAlarms, "a")).toEqual([]);
    live.handle({ type: "status", connection, cell_alarms: cell(summary("a"), stopped("b")) } as ServerMessage);
    expect(otherRobotAlarms(live.getSnapshot().cellAlarms, "a").map((s) => s.robot)).toEqual(["b"]);
    live.handle({ type: "status", connection } as ServerMessage);
    expect(otherRobotAlarms(live.getSnapshot().cellAlarms, "a").map((s) => s.robot)).toEqual(["b"]);
  });
});
