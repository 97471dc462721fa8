import { describe, expect, it, vi } from "vitest";
import type { Frame } from "../../generated/layout";
import { frameField } from "../layout/layoutInfo";
import { EVENT_LIMIT, LiveData } from "./liveData";
import { JOINT_PLOTS } from "../plots/plots";
import type { ConnectionStatus, ServerMessage } from "../api/protocol";

const connection = {
  state: "connected",
  reason: null,
  stale: false,
  rpi_ms: 10,
} as unknown as ConnectionStatus;

function frame(position0: number | null): Frame {
  const six = (v: number | null) => Array.from({ length: 6 }, () => v);
  return {
    joint_position: [position0, 1, 2, 3, 4, 5],
    joint_velocity: six(0),
    joint_motor_current: six(0),
    joint_motor_temperature: six(30),
    joint_torque: six(0),
    joint_external_torque: six(0),
    robot_state: 14,
  } as unknown as Frame;
}

describe("LiveData", () => {
  it("puts frames into the ring by the layout's channels and counts client gaps", () => {
    const clock = { t: 0 };
    const live = new LiveData(JOINT_PLOTS, { capacity: 128, now: () => clock.t });
    expect(live.channels.channelCount).toBe(6 * frameField("joint_position").count);
    live.setSocketState("open");
    live.handle({ type: "hello", robot: "r1", layout_version: 1, connection, control: { holder: null }, rate_hz: null });
    live.handle({
      type: "frames",
      frames: [
        { seq: 10, t: 100.0, frame: frame(7) },
        { seq: 11, t: 100.01, frame: frame(null) },
        { seq: 14, t: 100.04, frame: frame(9) },
      ],
    });
    expect(live.ring.size).toBe(3);
    expect(live.ring.valueAt(live.channels.channelOf("joint_position", 0), 0)).toBe(7);
    expect(live.ring.valueAt(live.channels.channelOf("joint_position", 0), 1)).toBeNaN();
    expect(live.ring.valueAt(live.channels.channelOf("joint_position", 5), 2)).toBe(5);
    expect(live.ring.timeAt(2)).toBeCloseTo(100_040);
    expect(live.clientGaps).toBe(2);
    live.handle({ type: "dropped", count: 4 });
    live.publish();
    const snap = live.getSnapshot();
    expect(snap.frame?.robot_state).toBe(14);
    expect(snap.dropped).toBe(4);
    expect(snap.health).toBe("connected");
  });

  it("publishes at once when the robot state or a flag changes", () => {
    const live = new LiveData(JOINT_PLOTS, { capacity: 16 });
    let published = 0;
    live.subscribe(() => published++);
    const f1 = { ...frame(1), emergency_stopped: false } as Frame;
    live.handle({ type: "frames", frames: [{ seq: 1, t: 1, frame: f1 }] });
    expect(published).toBe(1); // the first frame
    live.handle({ type: "frames", frames: [{ seq: 2, t: 1.01, frame: { ...f1 } as Frame }] });
    expect(published).toBe(1); // nothing a badge shows changed: wait for the periodic publish
    live.handle({ type: "frames", frames: [{ seq: 3, t: 1.02, frame: { ...f1, emergency_stopped: true } as Frame }] });
    expect(published).toBe(2);
    expect(live.getSnapshot().frame?.emergency_stopped).toBe(true);
    live.handle({ type: "frames", frames: [{ seq: 4, t: 1.03, frame: { ...f1, emergency_stopped: true, robot_state: 0 } as Frame }] });
    expect(published).toBe(3);
  });

  it("republishes on the page's beat once an interval has passed, and on its timer only when no beat comes", () => {
    vi.useFakeTimers({ now: 0 });
    try {
      const live = new LiveData(JOINT_PLOTS, { capacity: 16, now: Date.now, publishInterval_ms: 250 });
      const publishedAt: number[] = [];
      live.subscribe(() => publishedAt.push(Date.now()));
      live.start();
      live.publish();
      // Beats every 95 ms: a publish on the first beat 250 ms or more after the last; the timer
      // (every 250 ms) finds a publish younger than two intervals each time.
      for (let beat = 1; beat <= 6; beat++) {
        vi.advanceTimersByTime(95);
        live.beat();
      }
      expect(publishedAt).toEqual([0, 285, 570]);
      // No beats (a hidden page): the timer publishes once the last is two intervals old.
      vi.advanceTimersByTime(1000 - 570);
      expect(publishedAt).toEqual([0, 285, 570]); // the timer at 750 and 1000 ms: younger than 500 ms
      vi.advanceTimersByTime(1000);
      expect(publishedAt).toEqual([0, 285, 570, 1250, 1750]);
      live.stop();
    } finally {
      vi.useRealTimers();
    }
  });

  it("turns stale after a second without frames, and remembers since when", () => {
    const clock = { t: 1_000_000 };
    const live = new LiveData(JOINT_PLOTS, { capacity: 16, now: () => clock.t });
    live.setSocketState("open");
    live.handle({ type: "hello", robot: "r1", layout_version: 1, connection, control: { holder: null }, rate_hz: null });
    live.handle({ type: "frames", frames: [{ seq: 1, t: 1, frame: frame(1) }] });
    live.publish();
    expect(live.getSnapshot().health).toBe("connected");
    clock.t += 1500;
    live.publish();
    expect(live.getSnapshot().health).toBe("stale");
    expect(live.getSnapshot().staleSince_ms).toBe(1_000_000);
    live.setSocketState("closed");
    expect(live.getSnapshot().health).toBe("disconnected");
    expect(live.getSnapshot().staleSince_ms).toBe(1_000_000);
  });

  it("follows connection and control events, and keeps a bounded event list", () => {
    const live = new LiveData(JOINT_PLOTS, { capacity: 16 });
    live.setSocketState("open");
    // A service of another layout version: its hello is outside this build's contract on purpose.
    live.handle({ type: "hello", robot: "r1", layout_version: 99, connection, control: { holder: null }, rate_hz: null } as unknown as ServerMessage);
    expect(live.getSnapshot().layoutMismatch).toBe(99);
    live.handle({ type: "event", event: { kind: "connection", time: 1, state: "lost", reason: "timeout", text: "Connection lost: timeout" } });
    expect(live.getSnapshot().connection?.state).toBe("lost");
    expect(live.getSnapshot().health).toBe("disconnected");
    live.handle({ type: "event", event: { kind: "control", time: 2, holder: { user: "alice", since: 2 }, reason: null, text: "Control held by alice" } });
    expect(live.getSnapshot().control.holder?.user).toBe("alice");
    for (let i = 0; i < EVENT_LIMIT + 50; i++) {
      live.handle({ type: "event", event: { kind: "flag", time: i, flag: "servo_on", value: true, text: "Servo on flag set" } });
    }
    expect(live.getSnapshot().events).toHaveLength(EVENT_LIMIT);
    expect(live.getSnapshot().events[0]?.time).toBe(EVENT_LIMIT + 49);
  });
});
