import { describe, expect, it } from "vitest";
import { SampleRing } from "./ringBuffer";

describe("SampleRing", () => {
  it("keeps the newest samples and counts sequence numbers across wrap-around", () => {
    const ring = new SampleRing(4, 2);
    for (let i = 0; i < 10; i++) ring.push(i * 10, [i, -i]);
    expect(ring.endSeq).toBe(10);
    expect(ring.oldestSeq).toBe(6);
    expect(ring.size).toBe(4);
    expect([6, 7, 8, 9].map((s) => ring.valueAt(0, s))).toEqual([6, 7, 8, 9]);
    expect([6, 7, 8, 9].map((s) => ring.valueAt(1, s))).toEqual([-6, -7, -8, -9]);
    expect(ring.timeAt(9)).toBe(90);
    expect(ring.newestTime()).toBe(90);
  });

  it("stores missing channels as NaN and clamps times that go backwards", () => {
    const ring = new SampleRing(8, 3);
    ring.push(100, [1]);
    ring.push(50, [2, 3, 4]);
    expect(ring.valueAt(1, 0)).toBeNaN();
    expect(ring.timeAt(1)).toBe(100);
  });

  it("finds the first sample at or after a time by binary search", () => {
    const ring = new SampleRing(16, 1);
    for (let i = 0; i < 40; i++) ring.push(i * 10, [i]);
    expect(ring.oldestSeq).toBe(24);
    expect(ring.firstSeqAtOrAfter(0)).toBe(24); // older than held: the oldest held
    expect(ring.firstSeqAtOrAfter(305)).toBe(31);
    expect(ring.firstSeqAtOrAfter(310)).toBe(31);
    expect(ring.firstSeqAtOrAfter(10_000)).toBe(40);
  });

  it("allocates once: memory does not grow with the number of samples", () => {
    const ring = new SampleRing(1024, 54);
    const row = new Float64Array(54).fill(1);
    for (let i = 0; i < 200_000; i++) ring.push(i, row);
    expect(ring.size).toBe(1024);
    expect(ring.endSeq).toBe(200_000);
  });

  it("rejects a zero capacity", () => {
    expect(() => new SampleRing(0, 1)).toThrow();
  });
});
