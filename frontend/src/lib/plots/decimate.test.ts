import { describe, expect, it } from "vitest";
import { MinMaxBucketer, bucketWidthMs } from "./decimate";
import { SampleRing } from "../stream/ringBuffer";

function feedAll(b: MinMaxBucketer, samples: [number, number][]): void {
  for (const [t, v] of samples) b.feed(t, () => v);
}

describe("MinMaxBucketer", () => {
  it("emits two points per completed bucket: min and max in time order", () => {
    const b = new MinMaxBucketer([0], 100, 10);
    feedAll(b, [
      [0, 5],
      [10, 9], // max
      [20, 1], // min
      [30, 4],
      [100, 7], // opens bucket 1, completes bucket 0
    ]);
    const chunk = b.take();
    expect(chunk).not.toBeNull();
    expect(chunk?.buckets).toBe(1);
    expect(chunk?.xs[0]).toEqual([10, 20]);
    expect(chunk?.ys[0]).toEqual([9, 1]);
    expect(b.take()).toBeNull(); // the open bucket is not emitted yet
  });

  it("keeps a single peak however many samples a bucket has", () => {
    const b = new MinMaxBucketer([0], 1000, 10);
    const samples: [number, number][] = [];
    for (let t = 0; t < 1000; t++) samples.push([t, t === 437 ? 100 : 0]);
    samples.push([1000, 0]);
    feedAll(b, samples);
    const chunk = b.take();
    expect(chunk?.ys[0]).toEqual([0, 100]);
    expect(chunk?.xs[0]).toEqual([0, 437]);
  });

  it("bridges a short silence with repeats of the next real sample (no gap drawn)", () => {
    const b = new MinMaxBucketer([0], 10, 100, (t) => t, 100);
    feedAll(b, [
      [0, 1],
      [40, 5], // 3 empty buckets (10, 20, 30) within 100 ms
      [50, 6],
    ]);
    const chunk = b.take();
    expect(chunk?.buckets).toBe(5);
    expect(chunk?.ys[0]).toEqual([1, 1, 5, 5, 5, 5, 5, 5, 5, 5]);
    expect(chunk?.xs[0]).toEqual([0, 0, 40, 40, 40, 40, 40, 40, 40, 40]);
  });

  it("fills a gap with null pairs (a break in the line), capped", () => {
    const b = new MinMaxBucketer([0, 1], 10, 3);
    feedAll(b, [
      [0, 1],
      [1000, 2],
    ]); // 99 empty buckets between, capped at 3
    const chunk = b.take();
    expect(chunk?.buckets).toBe(4);
    expect(chunk?.ys[0]).toEqual([1, 1, null, null, null, null, null, null]);
    expect(chunk?.xs[1]?.length).toBe(8);
  });

  it("turns a bucket whose values are all non-finite into nulls", () => {
    const b = new MinMaxBucketer([0], 10, 3);
    b.feed(0, () => Number.NaN);
    b.feed(10, () => 1);
    expect(b.take()?.ys[0]).toEqual([null, null]);
  });

  it("aligns buckets to the epoch and applies the x mapping", () => {
    const b = new MinMaxBucketer([0], 10, 3, (t) => t + 1000);
    b.feed(25, () => 3);
    b.feed(31, () => 4);
    const chunk = b.take();
    expect(chunk?.xs[0]).toEqual([1025, 1025]);
  });

  it("reads from a ring: every trace gets the same number of points", () => {
    const ring = new SampleRing(64, 3);
    for (let i = 0; i < 50; i++) ring.push(i * 10, [i, 2 * i, 3 * i]);
    const b = new MinMaxBucketer([2, 0], 40, 10);
    b.feedRing(ring, ring.oldestSeq, ring.endSeq);
    const chunk = b.take();
    expect(chunk?.buckets).toBe(12); // buckets 0..11 complete, 12 open
    expect(chunk?.xs[0]?.length).toBe(24);
    expect(chunk?.ys[0]?.slice(0, 2)).toEqual([0, 9]); // channel 2 = 3i, samples 0..3
    expect(chunk?.ys[1]?.slice(0, 2)).toEqual([0, 3]);
  });

  it("gives a 2-minute window a fixed number of points from 100 Hz data", () => {
    const window_ms = 120_000;
    const b = new MinMaxBucketer([0], bucketWidthMs(window_ms, 400), 400);
    for (let t = 0; t <= window_ms; t += 10) b.feed(t, () => Math.sin(t / 1000));
    expect(b.take()?.buckets).toBe(400);
  });
});
