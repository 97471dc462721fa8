import { describe, expect, it, vi } from "vitest";
import { EXPIRY_SLACK_MS, reportEvery_ms, SessionIdleWatch, type SessionState } from "./sessionIdle";

const USER = { name: "olivia", role: "operator" };

/** A clock and timers the test moves by hand. */
function fakeTime() {
  let now = 0;
  const timers: { at: number; fn: () => void; id: number }[] = [];
  let next = 0;
  return {
    now: () => now,
    setTimer: (fn: () => void, ms: number) => {
      timers.push({ at: now + ms, fn, id: ++next });
      return next;
    },
    clearTimer: (id: unknown) => {
      const i = timers.findIndex((t) => t.id === id);
      if (i >= 0) timers.splice(i, 1);
    },
    pending: () => timers.length,
    /** Moves the clock, running each timer due on the way. */
    async advance(ms: number) {
      const end = now + ms;
      for (;;) {
        timers.sort((a, b) => a.at - b.at);
        const first = timers[0];
        if (first === undefined || first.at > end) break;
        timers.shift();
        now = first.at;
        first.fn();
        await Promise.resolve();
        await Promise.resolve();
      }
      now = end;
    },
  };
}

function session(left_s: number | null, timeout_s = 20): SessionState {
  return { user: USER, idle_timeout_s: left_s === null ? null : timeout_s, idle_expires_in_s: left_s };
}

async function settle() {
  for (let i = 0; i < 5; i++) await Promise.resolve();
}

describe("SessionIdleWatch", () => {
  it("reports a person's actions at most once per window, the last one at its end", async () => {
    const time = fakeTime();
    const report = vi.fn(async () => session(20));
    const watch = new SessionIdleWatch({ report, check: async () => session(20), onExpired: vi.fn(), now_ms: time.now, setTimer: time.setTimer, clearTimer: time.clearTimer });
    watch.start();
    await settle();
    const every = reportEvery_ms(20);
    expect(every).toBe(5000);
    watch.personActed();
    await settle();
    expect(report).toHaveBeenCalledTimes(1);
    // A burst of clicks within the window: one trailing report at the window's end.
    await time.advance(1000);
    watch.personActed();
    watch.personActed();
    await time.advance(3000);
    watch.personActed();
    expect(report).toHaveBeenCalledTimes(1);
    await time.advance(1000);
    expect(report).toHaveBeenCalledTimes(2);
    // Nothing more while nobody acts, however long the page stays open.
    await time.advance(4 * every);
    expect(report).toHaveBeenCalledTimes(2);
    watch.stop();
  });

  it("says so at once when the session has idled out, and reports nothing after", async () => {
    const time = fakeTime();
    const onExpired = vi.fn();
    const check = vi.fn(async (): Promise<SessionState | null> => session(20));
    const report = vi.fn(async () => session(20));
    const watch = new SessionIdleWatch({ report, check, onExpired, now_ms: time.now, setTimer: time.setTimer, clearTimer: time.clearTimer });
    watch.start();
    await settle();
    check.mockImplementation(async () => ({ user: null }));
    await time.advance(20_000 + EXPIRY_SLACK_MS - 1);
    expect(onExpired).not.toHaveBeenCalled();
    await time.advance(1);
    await settle();
    expect(check).toHaveBeenCalledTimes(2);
    expect(onExpired).toHaveBeenCalledTimes(1);
    watch.personActed();
    await time.advance(60_000);
    expect(report).not.toHaveBeenCalled();
    expect(onExpired).toHaveBeenCalledTimes(1);
    expect(time.pending()).toBe(0);
  });

  it("waits for the new deadline when the session was renewed meanwhile", async () => {
    const time = fakeTime();
    const onExpired = vi.fn();
    const check = vi.fn(async () => session(20));
    const watch = new SessionIdleWatch({ report: async () => session(20), check, onExpired, now_ms: time.now, setTimer: time.setTimer, clearTimer: time.clearTimer });
    watch.start();
    await settle();
    check.mockImplementation(async () => session(12)); // another window's person acted
    await time.advance(20_000 + EXPIRY_SLACK_MS);
    await settle();
    expect(check).toHaveBeenCalledTimes(2);
    check.mockImplementation(async () => ({ user: null, idle_timeout_s: null, idle_expires_in_s: null }) as SessionState);
    await time.advance(12_000 + EXPIRY_SLACK_MS);
    await settle();
    expect(onExpired).toHaveBeenCalledTimes(1);
  });

  it("a refused activity report (401) is the end of the session", async () => {
    const time = fakeTime();
    const onExpired = vi.fn();
    const watch = new SessionIdleWatch({ report: async () => null, check: async () => session(20), onExpired, now_ms: time.now, setTimer: time.setTimer, clearTimer: time.clearTimer });
    watch.start();
    await settle();
    watch.personActed();
    await settle();
    expect(onExpired).toHaveBeenCalledTimes(1);
  });

  it("an API token's session never idles out: no deadline is kept", async () => {
    const time = fakeTime();
    const watch = new SessionIdleWatch({ report: async () => session(null), check: async () => session(null), onExpired: vi.fn(), now_ms: time.now, setTimer: time.setTimer, clearTimer: time.clearTimer });
    watch.start();
    await settle();
    expect(time.pending()).toBe(0);
  });

  it("a service that does not answer is asked again", async () => {
    const time = fakeTime();
    const onExpired = vi.fn();
    const check = vi.fn(async (): Promise<SessionState | null> => {
      throw new Error("offline");
    });
    const watch = new SessionIdleWatch({ report: async () => session(20), check, onExpired, now_ms: time.now, setTimer: time.setTimer, clearTimer: time.clearTimer });
    watch.start();
    await settle();
    check.mockImplementation(async () => ({ user: null }));
    await time.advance(2000);
    await settle();
    expect(onExpired).toHaveBeenCalledTimes(1);
  });
});
