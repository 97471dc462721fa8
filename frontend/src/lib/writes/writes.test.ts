import { describe, expect, it } from "vitest";
import { WriteTracker, classifyWriteResponse, performWrite, sameValue, writeKey } from "./writes";

function clock(start = 1000) {
  const c = { t: start, now: () => c.t };
  return c;
}

describe("classifyWriteResponse", () => {
  it("maps the contract's statuses", () => {
    expect(classifyWriteResponse(200, { outcome: "confirmed", latency_ms: 12.5, seq: 812 })).toEqual({
      kind: "confirmed",
      latency_ms: 12.5,
      seq: 812,
    });
    expect(classifyWriteResponse(200, { outcome: "confirmed", latency_ms: 3, seq: null })).toMatchObject({ seq: null });
    expect(classifyWriteResponse(504, { detail: { reason: "no echo", robot_reports: {} } })).toEqual({
      kind: "timeout",
      reason: "no echo",
    });
    expect(
      classifyWriteResponse(422, { detail: { field: "analog_output.0", reason: "outside 4–20 mA" } }),
    ).toEqual({ kind: "refused", reason: "outside 4–20 mA" });
    expect(classifyWriteResponse(409, { detail: { reason: "control not held" } })).toEqual({
      kind: "refused",
      reason: "control not held",
    });
    expect(classifyWriteResponse(401, null)).toEqual({ kind: "refused", reason: "not logged in" });
    expect(classifyWriteResponse(429, "")).toEqual({ kind: "refused", reason: "too many requests: try again shortly" });
    expect(classifyWriteResponse(404, { detail: { reason: "unknown robot 'x'; known: a", field: "name" } })).toEqual({
      kind: "refused",
      reason: "unknown robot 'x'; known: a",
    });
    expect(classifyWriteResponse(403, { detail: "viewer" })).toEqual({ kind: "refused", reason: "viewer" });
    expect(classifyWriteResponse(422, { detail: [{ loc: ["body"], msg: "bad json" }] })).toEqual({
      kind: "refused",
      reason: "bad json",
    });
    expect(classifyWriteResponse(500, null).kind).toBe("refused");
  });
});

describe("WriteTracker", () => {
  const key = writeKey("controlbox_do", 2);

  it("shows the actual value while idle", () => {
    const t = new WriteTracker();
    expect(t.view(key, false)).toMatchObject({ shown: false, pending: false, reason: null });
    expect(t.view(key, undefined).shown).toBeNull();
  });

  it("pending until confirmed, then the confirmed value until the frame shows it, then actual", () => {
    const c = clock();
    const t = new WriteTracker(c.now, 1000);
    const token = t.begin([key], [true]);
    expect(t.view(key, false)).toMatchObject({ shown: "pending", pending: true });
    c.t += 30;
    t.settle([key], token, { kind: "confirmed", latency_ms: 30, seq: null });
    // The PATCH answer beat the WebSocket frame: still show what the robot confirmed.
    expect(t.view(key, false)).toMatchObject({ shown: true, pending: false, phase: "confirmed" });
    // The frame arrives: actual = requested.
    expect(t.view(key, true).shown).toBe(true);
    // Later the robot changes it by itself: the display follows the robot, not the request.
    c.t += 2000;
    expect(t.view(key, false).shown).toBe(false);
  });

  it("a write confirmed by frame N shows as written until the display shows frame N or newer, however late", () => {
    const c = clock();
    const t = new WriteTracker(c.now, 1000);
    t.showing(490);
    const token = t.begin([key], [true]);
    t.settle([key], token, { kind: "confirmed", latency_ms: 30, seq: 500 });
    // A busy machine: the stream lags the answer by seconds; its older frames still say off.
    c.t += 3000;
    t.showing(495);
    expect(t.view(key, false).shown).toBe(true);
    // Frame 500 reached the display: the robot's actual value from now on (subscribers told).
    let calls = 0;
    t.subscribe(() => calls++);
    t.showing(500);
    expect(calls).toBe(1);
    expect(t.view(key, true).shown).toBe(true);
    expect(t.view(key, false).shown).toBe(false); // turned off again by someone else since
    // Already there when the answer came: nothing held.
    const again = t.begin([key], [false]);
    t.settle([key], again, { kind: "confirmed", latency_ms: 10, seq: 499 });
    expect(t.view(key, true).shown).toBe(true);
    // A stream that stopped does not hold a value for ever.
    const third = t.begin([key], [false]);
    t.settle([key], third, { kind: "confirmed", latency_ms: 10, seq: 900 });
    expect(t.view(key, true).shown).toBe(false);
    c.t += 10_001;
    expect(t.view(key, true).shown).toBe(true);
  });

  it("a refusal keeps the actual value and shows the reason until the next write", () => {
    const c = clock();
    const t = new WriteTracker(c.now);
    const token = t.begin([key], [true]);
    t.settle([key], token, { kind: "refused", reason: "control not held" });
    expect(t.view(key, false)).toEqual({ shown: false, pending: false, reason: "control not held", phase: "refused" });
    const again = t.begin([key], [true]);
    expect(t.view(key, false).reason).toBeNull();
    t.settle([key], again, { kind: "timeout", reason: "no confirmation" });
    expect(t.view(key, false)).toMatchObject({ shown: false, reason: "no confirmation", phase: "timeout" });
    t.clear(key);
    expect(t.view(key, false).phase).toBe("idle");
  });

  it("an older answer does not settle a newer write of the same control", () => {
    const t = new WriteTracker();
    const first = t.begin([key], [true]);
    const second = t.begin([key], [false]);
    t.settle([key], first, { kind: "refused", reason: "stale answer" });
    expect(t.view(key, true).pending).toBe(true);
    t.settle([key], second, { kind: "confirmed", latency_ms: null, seq: null });
    expect(t.view(key, false).shown).toBe(false);
  });

  it("tracks several keys of one write together", () => {
    const t = new WriteTracker();
    const keys = [writeKey("analog_output_type", 0), writeKey("analog_output", 0)];
    const token = t.begin(keys, [1, 5]);
    expect(keys.every((k) => t.isPending(k))).toBe(true);
    t.settle(keys, token, { kind: "refused", reason: "out of range" });
    expect(keys.map((k) => t.view(k, 0).reason)).toEqual(["out of range", "out of range"]);
  });

  it("notifies subscribers on every change", () => {
    const t = new WriteTracker();
    let calls = 0;
    const unsubscribe = t.subscribe(() => calls++);
    const token = t.begin([key], [true]);
    t.settle([key], token, { kind: "confirmed", latency_ms: 1, seq: null });
    unsubscribe();
    t.begin([key], [false]);
    expect(calls).toBe(2);
    expect(t.getVersion()).toBe(3);
  });
});

describe("performWrite", () => {
  const key = writeKey("bit_input_registers", 40);

  it("is pending while the request is outstanding and settles by the answer", async () => {
    const t = new WriteTracker();
    let answer: (v: { status: number; body: unknown }) => void = () => undefined;
    const done = performWrite(t, [key], [true], () => new Promise((resolve) => (answer = resolve)));
    expect(t.view(key, false).shown).toBe("pending");
    answer({ status: 200, body: { outcome: "confirmed", latency_ms: 11 } });
    await expect(done).resolves.toEqual({ kind: "confirmed", latency_ms: 11, seq: null });
    expect(t.view(key, false).shown).toBe(true);
  });

  it("turns a network failure into a refusal with its reason", async () => {
    const t = new WriteTracker();
    const outcome = await performWrite(t, [key], [true], () => Promise.reject(new Error("offline")));
    expect(outcome).toEqual({ kind: "refused", reason: "request failed: offline" });
    expect(t.view(key, false)).toMatchObject({ shown: false, reason: "request failed: offline" });
  });

  it("a 504 is a timeout that leaves the display truthful", async () => {
    const t = new WriteTracker();
    await performWrite(t, [key], [true], async () => ({
      status: 504,
      body: { detail: { reason: "no confirmation in 500 ms", robot_reports: {} } },
    }));
    expect(t.view(key, false)).toMatchObject({ shown: false, phase: "timeout", reason: "no confirmation in 500 ms" });
  });
});

describe("sameValue", () => {
  it("compares booleans exactly and REALs with float32 tolerance", () => {
    expect(sameValue(true, true)).toBe(true);
    expect(sameValue(true, false)).toBe(false);
    expect(sameValue(12.5, Math.fround(12.5))).toBe(true);
    expect(sameValue(12.3, Math.fround(12.3))).toBe(true);
    expect(sameValue(12.3, 12.4)).toBe(false);
    expect(sameValue(null, 1)).toBe(false);
  });
});
