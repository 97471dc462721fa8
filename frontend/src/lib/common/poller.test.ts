import { afterEach, beforeEach, describe, expect, it, vi } from "vitest";
import { Poller, type Fetched } from "./poller";

/** A fetch whose answers the test gives, one per call, in order. */
function scripted<T>() {
  const waiting: ((answer: Fetched<T>) => void)[] = [];
  let count = 0;
  return {
    calls: () => count,
    fetch: () =>
      new Promise<Fetched<T>>((resolve) => {
        count++;
        waiting.push(resolve);
      }),
    async answer(answer: Fetched<T>) {
      waiting.shift()?.(answer);
      await vi.advanceTimersByTimeAsync(0);
    },
  };
}

beforeEach(() => vi.useFakeTimers());
afterEach(() => vi.useRealTimers());

describe("Poller", () => {
  it("asks once at a time, publishes each answer, and asks again after its interval", async () => {
    const s = scripted<number>();
    const poller = new Poller(s.fetch, 3000);
    let published = 0;
    poller.subscribe(() => published++);
    poller.start();
    await vi.advanceTimersByTimeAsync(10_000);
    expect(s.calls()).toBe(1); // a slow answer: nothing piles up behind it
    await s.answer({ ok: true, value: 7 });
    expect(published).toBe(1);
    expect(poller.getSnapshot()).toEqual({ value: 7, error: null, status: null, stale: false, loaded: true });
    await vi.advanceTimersByTimeAsync(2999);
    expect(s.calls()).toBe(1);
    await vi.advanceTimersByTimeAsync(1);
    expect(s.calls()).toBe(2);
    poller.stop();
  });

  it("keeps the last value, marked stale, with the reason and status of a refusal", async () => {
    const s = scripted<number>();
    const poller = new Poller(s.fetch, 1000);
    poller.start();
    await s.answer({ ok: false, status: 401, reason: "login required" });
    expect(poller.getSnapshot()).toMatchObject({ value: null, error: "login required", status: 401, stale: false, loaded: true });
    await vi.advanceTimersByTimeAsync(1000);
    await s.answer({ ok: true, value: 1 });
    await vi.advanceTimersByTimeAsync(1000);
    await s.answer({ ok: false, status: 503, reason: "not ready" });
    expect(poller.getSnapshot()).toMatchObject({ value: 1, error: "not ready", status: 503, stale: true });
    poller.stop();
  });

  it("turns a fetch that throws into an error (status 0) and goes on", async () => {
    let n = 0;
    const poller = new Poller<number>(async () => {
      if (++n === 1) throw new Error("network down");
      return { ok: true, value: n };
    }, 1000);
    poller.start();
    await vi.advanceTimersByTimeAsync(0);
    expect(poller.getSnapshot()).toMatchObject({ error: "network down", status: 0 });
    await vi.advanceTimersByTimeAsync(1000);
    expect(poller.getSnapshot()).toMatchObject({ value: 2, error: null });
    poller.stop();
  });

  it("asks at once on refresh and drops the answer of the request it replaced, and any after a stop", async () => {
    const s = scripted<string>();
    const poller = new Poller(s.fetch, 1000);
    poller.start();
    poller.refresh();
    expect(s.calls()).toBe(2);
    await s.answer({ ok: true, value: "old" });
    expect(poller.getSnapshot().loaded).toBe(false);
    await s.answer({ ok: true, value: "new" });
    expect(poller.getSnapshot().value).toBe("new");
    poller.stop();
    await vi.advanceTimersByTimeAsync(5000);
    expect(s.calls()).toBe(2);
  });
});
