import { readFileSync } from "node:fs";
import { afterEach, beforeEach, describe, expect, it, vi } from "vitest";
import { PLANT_API_TS_PATH, PLANT_OPENAPI_PATH, generateApiTs } from "../../../scripts/generate-api.mjs";
import { ALARMS_POLL_MS, NODES_POLL_MS, PlantPoller, type Answer } from "./plantApi";
import type { PlantAlarms, PlantNode, PlantPeer, PlantShifts } from "./plant";

describe("src/generated/plantApi.ts", { timeout: 60_000 }, () => {
  it("is what docs/plant-openapi.json generates (else run `make codegen`)", async () => {
    const expected = await generateApiTs(readFileSync(PLANT_OPENAPI_PATH, "utf8"), "plant-openapi.json");
    const current = readFileSync(PLANT_API_TS_PATH, "utf8");
    expect(current === expected, "src/generated/plantApi.ts is stale: run `make codegen`").toBe(true);
  });
});

const NODE: PlantNode = { group: "g", node: "cell-1", online: true, since: 1, bd_seq: 0, hmi_url: null, area: null, devices: [] };
const SHIFTS: PlantShifts = { since: 1000, until: 2000, time_zone: "UTC", robots: [] };

describe("the plant's poller", () => {
  beforeEach(() => vi.useFakeTimers());
  afterEach(() => vi.useRealTimers());

  function fakeApi(nodes: () => Answer<PlantNode[]>) {
    const since: number[] = [];
    return {
      since,
      api: {
        nodes: () => Promise.resolve(nodes()),
        alarms: (s: number): Promise<Answer<PlantAlarms>> => {
          since.push(s);
          return Promise.resolve({ ok: true, data: { transitions: [], figures: [] } });
        },
        shifts: (): Promise<Answer<PlantShifts>> => Promise.resolve({ ok: true, data: SHIFTS }),
      },
    };
  }

  it("keeps the last nodes when the plant stops answering, and says so", async () => {
    let answer: Answer<PlantNode[]> = { ok: true, data: [NODE] };
    const { api } = fakeApi(() => answer);
    const poller = new PlantPoller(api, () => 5000);
    poller.start();
    await vi.advanceTimersByTimeAsync(0);
    expect(poller.getSnapshot()).toMatchObject({ nodes: [NODE], error: null, stale: false, loaded: true, answered_ms: 5000 });
    answer = { ok: false, status: 503, reason: "HTTP 503" };
    await vi.advanceTimersByTimeAsync(NODES_POLL_MS);
    expect(poller.getSnapshot()).toMatchObject({ nodes: [NODE], error: "HTTP 503", stale: true, loginNeeded: false });
    answer = { ok: false, status: 401, reason: "login required" };
    await vi.advanceTimersByTimeAsync(NODES_POLL_MS);
    expect(poller.getSnapshot().loginNeeded).toBe(true);
    poller.stop();
  });

  it("asks for the alarms of the shift once it knows when the shift began", async () => {
    const { api, since } = fakeApi(() => ({ ok: true, data: [] }));
    const poller = new PlantPoller(api, () => 10_000_000);
    poller.start();
    await vi.advanceTimersByTimeAsync(0);
    await vi.advanceTimersByTimeAsync(1000);
    expect(since[0]).toBe(10_000 - 8 * 3600);
    expect(since.at(-1)).toBe(SHIFTS.since);
    poller.stop();
    const count = since.length;
    await vi.advanceTimersByTimeAsync(5000);
    expect(since.length).toBe(count);
  });

  it("follows the plant's peers with the alarms: a peer that stops answering is published", async () => {
    let answering = true;
    const { api } = fakeApi(() => ({ ok: true, data: [NODE] }));
    const peers = (): Promise<Answer<PlantPeer[]>> =>
      Promise.resolve({ ok: true, data: [{ url: "http://p:8101", answering, since: 1, error: answering ? null : "timed out", nodes: 1 }] });
    const poller = new PlantPoller({ ...api, peers }, () => 5000);
    poller.start();
    await vi.advanceTimersByTimeAsync(0);
    expect(poller.getSnapshot().peers.map((p) => p.answering)).toEqual([true]);
    answering = false;
    await vi.advanceTimersByTimeAsync(ALARMS_POLL_MS);
    expect(poller.getSnapshot().peers.map((p) => [p.answering, p.error])).toEqual([[false, "timed out"]]);
    poller.stop();
  });
});
