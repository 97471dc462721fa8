import { afterEach, beforeEach, describe, expect, it, vi } from "vitest";
import { alarmWords, FleetPoller, fleetTile, knownRobots, type RobotsAnswer } from "./fleet";
import type { RobotSummary } from "../api/protocol";

function summary(name: string, overrides: Partial<RobotSummary> = {}): RobotSummary {
  return {
    name,
    host: "127.0.0.3",
    mode: "exclusive_owner",
    rpi_ms: 10,
    model: "M1013",
    identity: null,
    connection: "connected",
    connection_reason: null,
    holder: null,
    robot_state: 14,
    robot_state_name: "STANDALONE_RUNNING",
    default: false,
    ...overrides,
  };
}

describe("fleetTile", () => {
  it("says what a connected robot does and who holds it, with links to its panel and kiosk", () => {
    const tile = fleetTile(summary("m1013", { holder: { user: "alice", since: 1 } }));
    expect(tile).toMatchObject({
      name: "m1013",
      model: "M1013",
      link: "connected",
      linkWords: "connected",
      stateValue: 14,
      holder: "alice",
      readOnly: false,
      panelHref: "/?robot=m1013",
      kioskHref: "/kiosk?robot=m1013",
    });
  });

  it("shows no state for a robot whose link is down, and says why the link is down", () => {
    const tile = fleetTile(summary("m0609", { connection: "lost", connection_reason: "no T→O for 640 ms", robot_state: 14 }));
    expect(tile.stateValue).toBeNull();
    expect(tile.linkWords).toBe("lost: no T→O for 640 ms");
    expect(tile.holder).toBeNull();
  });

  it("sums up the robot's alarms: the most urgent in words, the counts", () => {
    expect(fleetTile(summary("a")).alarmWords).toBe("—");
    expect(fleetTile(summary("a")).topAlarmWords).toBeNull();
    const top = {
      id: "a:emergency_stop",
      key: "emergency_stop",
      robot: "a",
      name: "Emergency stop",
      label: null,
      tag: null,
      message: null,
      priority: "critical" as const,
      priority_rank: 0,
      colour: "red",
      state: "active_unacknowledged" as const,
      active: true,
      activated_at: 1,
      changed_at: 1,
    };
    const alarms = { robot: "a", active: 3, annunciated: 2, unacknowledged: 1, shelved: 1, suppressed: 1, highest_priority: "critical" as const, top };
    const tile = fleetTile(summary("a", { alarms }));
    expect(tile.alarms).toEqual(alarms);
    expect(tile.topAlarmWords).toBe("Emergency stop — critical, active, unacknowledged");
    expect(tile.alarmWords).toBe("2 alarms (1 unacknowledged), 1 shelved, 1 suppressed by design");
    expect(alarmWords({ active: 0, unacknowledged: 0, shelved: 0, highest_priority: null })).toBe("none");
  });

  it("says how old the newest frame is, whether it is stale and how many frames went missing", () => {
    const live = fleetTile(summary("a", { frame_age_s: 0.012, stale: false, gaps: 12, gaps_per_min: 3 }));
    expect(live).toMatchObject({ frameAgeWords: "12 ms", stale: false, gapsPerMin: 3, gaps: 12 });
    expect(live.gapsWords).toBe("3 in the last minute (12 on this connection)");
    const quiet = fleetTile(summary("a", { frame_age_s: 2.5, stale: true, gaps: 0, gaps_per_min: 0 }));
    expect(quiet).toMatchObject({ frameAgeWords: "2.5 s", stale: true, gapsWords: "none in the last minute (0 on this connection)" });
    const down = fleetTile(summary("a", { connection: "lost", frame_age_s: null, gaps: null, gaps_per_min: null }));
    expect(down).toMatchObject({ frameAgeWords: "no frame yet", stale: true, gapsWords: "not connected" });
  });

  it("marks an input-only robot read-only and an unknown model as unknown", () => {
    const tile = fleetTile(summary("beside-plc", { mode: "input_only", model: null }));
    expect(tile.readOnly).toBe(true);
    expect(tile.model).toBeNull();
  });
});

describe("FleetPoller", () => {
  beforeEach(() => {
    vi.useFakeTimers();
  });
  afterEach(() => {
    vi.useRealTimers();
  });

  /** A fetch whose answers the test hands out one by one. */
  function scripted() {
    const pending: ((answer: RobotsAnswer) => void)[] = [];
    const calls = { count: 0 };
    const fetchRobots = () =>
      new Promise<RobotsAnswer>((resolve) => {
        calls.count++;
        pending.push(resolve);
      });
    const answer = async (a: RobotsAnswer) => {
      const resolve = pending.shift();
      if (resolve === undefined) throw new Error("no request outstanding");
      resolve(a);
      await vi.advanceTimersByTimeAsync(0);
    };
    return { fetchRobots, answer, calls, pending };
  }

  it("polls one request at a time and publishes a tile per robot", async () => {
    const s = scripted();
    const poller = new FleetPoller(s.fetchRobots, 1000);
    let published = 0;
    poller.subscribe(() => published++);
    poller.start();
    expect(s.calls.count).toBe(1);
    // A slow answer: no second request piles up behind it.
    await vi.advanceTimersByTimeAsync(5000);
    expect(s.calls.count).toBe(1);
    expect(poller.getSnapshot().loaded).toBe(false);
    await s.answer({ ok: true, robots: [summary("a"), summary("b", { connection: "lost" })] });
    expect(published).toBe(1);
    expect(poller.getSnapshot().tiles.map((t) => [t.name, t.link])).toEqual([
      ["a", "connected"],
      ["b", "lost"],
    ]);
    expect(poller.getSnapshot()).toMatchObject({ loaded: true, stale: false, error: null });
    await vi.advanceTimersByTimeAsync(999);
    expect(s.calls.count).toBe(1);
    await vi.advanceTimersByTimeAsync(1);
    expect(s.calls.count).toBe(2);
    poller.stop();
  });

  it("keeps the last tiles, marked stale, while the service does not answer", async () => {
    const s = scripted();
    const poller = new FleetPoller(s.fetchRobots, 1000);
    poller.start();
    await s.answer({ ok: true, robots: [summary("a")] });
    await vi.advanceTimersByTimeAsync(1000);
    await s.answer({ ok: false, reason: "HTTP 503" });
    expect(poller.getSnapshot()).toMatchObject({ stale: true, error: "HTTP 503" });
    expect(poller.getSnapshot().tiles.map((t) => t.name)).toEqual(["a"]);
    expect(knownRobots(poller.getSnapshot())).toEqual(["a"]);
    await vi.advanceTimersByTimeAsync(1000);
    await s.answer({ ok: true, robots: [summary("a"), summary("b")] });
    expect(poller.getSnapshot()).toMatchObject({ stale: false, error: null });
    expect(poller.getSnapshot().tiles).toHaveLength(2);
    poller.stop();
  });

  it("turns a failed fetch into an error and goes on polling", async () => {
    let n = 0;
    const poller = new FleetPoller(async () => {
      n++;
      if (n === 1) throw new Error("network down");
      return { ok: true, robots: [summary("a")] };
    }, 1000);
    poller.start();
    await vi.advanceTimersByTimeAsync(0);
    expect(poller.getSnapshot()).toMatchObject({ loaded: true, error: "network down", stale: false, answered: false });
    // No list yet: the robots are unknown, not "none".
    expect(knownRobots(poller.getSnapshot())).toBeNull();
    await vi.advanceTimersByTimeAsync(1000);
    expect(poller.getSnapshot()).toMatchObject({ error: null, answered: true });
    expect(knownRobots(poller.getSnapshot())).toEqual(["a"]);
    poller.stop();
  });

  it("drops answers that come after a stop or a refresh", async () => {
    const s = scripted();
    const poller = new FleetPoller(s.fetchRobots, 1000);
    poller.start();
    poller.refresh(); // a second request; the first one's answer is now moot
    expect(s.calls.count).toBe(2);
    await s.answer({ ok: true, robots: [summary("old")] });
    expect(poller.getSnapshot().loaded).toBe(false);
    await s.answer({ ok: true, robots: [summary("new")] });
    expect(poller.getSnapshot().tiles.map((t) => t.name)).toEqual(["new"]);
    await vi.advanceTimersByTimeAsync(1000);
    expect(s.calls.count).toBe(3);
    poller.stop();
    await s.answer({ ok: true, robots: [summary("late")] });
    expect(poller.getSnapshot().tiles.map((t) => t.name)).toEqual(["new"]);
    await vi.advanceTimersByTimeAsync(5000);
    expect(s.calls.count).toBe(3);
  });
});
