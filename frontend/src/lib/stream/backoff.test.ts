import { describe, expect, it } from "vitest";
import { Backoff } from "./backoff";

const opts = { initial_ms: 100, max_ms: 2000, factor: 2, jitter: 0.5 };

describe("Backoff", () => {
  it("grows exponentially up to the cap (no randomness: r = 0)", () => {
    const b = new Backoff(opts, () => 0);
    const delays = Array.from({ length: 8 }, () => b.next_ms());
    expect(delays).toEqual([100, 200, 400, 800, 1600, 2000, 2000, 2000]);
    expect(b.attempt).toBe(8);
  });

  it("jitters within [(1 - jitter)·d, d]", () => {
    const b = new Backoff(opts, () => 1);
    expect(b.next_ms()).toBe(50);
    expect(b.next_ms()).toBe(100);
    let seed = 7;
    const rand = () => {
      seed = (seed * 16807) % 2147483647;
      return seed / 2147483647;
    };
    const c = new Backoff(opts, rand);
    for (let i = 0; i < 50; i++) {
      const ceiling = c.ceiling_ms();
      const d = c.next_ms();
      expect(d).toBeGreaterThanOrEqual(ceiling * 0.5);
      expect(d).toBeLessThanOrEqual(ceiling);
    }
  });

  it("spreads clients apart: different random draws give different delays", () => {
    const a = new Backoff(opts, () => 0.1);
    const b = new Backoff(opts, () => 0.9);
    a.next_ms();
    b.next_ms();
    expect(a.next_ms()).not.toBe(b.next_ms());
  });

  it("starts over after a reset", () => {
    const b = new Backoff(opts, () => 0);
    b.next_ms();
    b.next_ms();
    b.next_ms();
    b.reset();
    expect(b.next_ms()).toBe(100);
  });

  it("never overflows after very many attempts", () => {
    const b = new Backoff(opts, () => 0);
    for (let i = 0; i < 10_000; i++) b.next_ms();
    expect(b.next_ms()).toBe(2000);
  });

  it("rejects nonsense options", () => {
    expect(() => new Backoff({ ...opts, initial_ms: 0 })).toThrow();
    expect(() => new Backoff({ ...opts, max_ms: 10 })).toThrow();
    expect(() => new Backoff({ ...opts, jitter: 2 })).toThrow();
    expect(() => new Backoff({ ...opts, factor: 0.5 })).toThrow();
  });
});
