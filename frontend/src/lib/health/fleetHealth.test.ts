import { afterEach, beforeEach, describe, expect, it, vi } from "vitest";
import { FleetHealthPoller, healthCell } from "./fleetHealth";
import type { Fetched } from "../common/poller";
import { joint, report, SIX_OK } from "./healthTestSupport";
import type { HealthAnswer } from "./healthTypes";

beforeEach(() => vi.useFakeTimers());
afterEach(() => vi.useRealTimers());

const ok = (value: HealthAnswer): Fetched<HealthAnswer> => ({ ok: true, value });

describe("the fleet's health column", () => {
  it("shows a robot's worst verdict in words, linked to its health page", () => {
    const cell = healthCell("m1013", ok(report([joint(1), joint(3, { verdict: "act" }), joint(4, { verdict: "watch" })])));
    expect(cell).toEqual({ verdict: "act", words: "act: J3", maintenanceDue: true, href: "/health?robot=m1013" });
    expect(healthCell("m0609", ok(report(SIX_OK)))).toMatchObject({ verdict: "ok", words: "ok", maintenanceDue: false });
  });

  it("says a robot without a baseline has none, and why a robot's health is not known, never 'ok'", () => {
    expect(healthCell("a", ok(report(SIX_OK, { baseline: null }))).words).toBe("no baseline yet");
    expect(healthCell("a", { ok: false, status: 401, reason: "login required" })).toMatchObject({ verdict: null, words: "not known: login required" });
    expect(healthCell("a", null)).toMatchObject({ verdict: null, words: "asking…" });
  });

  it("asks robot by robot, one request at a time, then again after its interval; a new robot at once", async () => {
    const asked: string[] = [];
    const poller = new FleetHealthPoller(async (robot) => {
      asked.push(robot);
      return ok(report(robot === "b" ? [joint(2, { verdict: "watch" })] : SIX_OK));
    }, 10_000);
    poller.setRobots(["a", "b"]);
    expect(poller.getSnapshot().get("a")?.words).toBe("asking…");
    poller.start();
    await vi.advanceTimersByTimeAsync(0);
    expect(asked).toEqual(["a", "b"]);
    expect(poller.getSnapshot().get("b")).toMatchObject({ verdict: "watch", words: "watch: J2" });
    await vi.advanceTimersByTimeAsync(9_999);
    expect(asked).toHaveLength(2);
    await vi.advanceTimersByTimeAsync(1);
    expect(asked).toEqual(["a", "b", "a", "b"]);
    poller.setRobots(["a", "b", "c"]);
    await vi.advanceTimersByTimeAsync(0);
    expect(asked.slice(4)).toEqual(["a", "b", "c"]);
    poller.setRobots(["c"]);
    expect([...poller.getSnapshot().keys()]).toEqual(["c"]);
    poller.stop();
    await vi.advanceTimersByTimeAsync(60_000);
    expect(asked).toHaveLength(7);
  });
});
