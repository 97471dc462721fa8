import { describe, expect, it } from "vitest";
import { ARMS } from "../generated/arms";
import { ArmChain, originOf } from "./armKinematics";
import { ChannelMap, JOINT_PLOTS } from "./plots";
import { SampleRing } from "./ringBuffer";
import { RobotPoseFeed, TcpTrail } from "./robotPose";

describe("TcpTrail", () => {
  it("keeps only the window behind the newest point, oldest first", () => {
    const trail = new TcpTrail(10, 100);
    for (let t = 0; t <= 300; t += 50) trail.push(t, t, 2 * t, 3 * t);
    const out = new Float32Array(30);
    const n = trail.copyInto(out);
    expect(n).toBe(3); // 200, 250, 300
    expect(Array.from(out.subarray(0, 9))).toEqual([200, 400, 600, 250, 500, 750, 300, 600, 900]);
  });

  it("wraps around without growing", () => {
    const trail = new TcpTrail(4, 1e9);
    for (let t = 0; t < 10; t++) trail.push(t, t, 0, 0);
    const out = new Float32Array(12);
    expect(trail.copyInto(out)).toBe(4);
    expect([out[0], out[3], out[6], out[9]]).toEqual([6, 7, 8, 9]);
  });
});

describe("RobotPoseFeed", () => {
  const channels = new ChannelMap(JOINT_PLOTS);
  const row = (q: readonly number[]) => {
    const r = new Float64Array(channels.channelCount).fill(Number.NaN);
    q.forEach((v, i) => (r[channels.channelOf("joint_position", i)] = v));
    return r;
  };

  it("follows the newest joints and traces the flange", () => {
    const ring = new SampleRing(1000, channels.channelCount);
    const feed = new RobotPoseFeed(new ArmChain(ARMS.M1013), ring, channels, 1000, 100);
    expect(feed.update()).toBe(false);
    expect(feed.hasPose).toBe(false);
    ring.push(0, row([30, 0, 90, 0, 90, 0]));
    expect(feed.update()).toBe(true);
    const tcp = originOf(feed.frames[6] as Float64Array).map((v) => v * 1000);
    expect(tcp[0]).toBeCloseTo(466.9, 1);
    expect(tcp[1]).toBeCloseTo(309.4, 1);
    expect(tcp[2]).toBeCloseTo(651.5, 1);
    expect(feed.update()).toBe(false); // nothing new
    for (let i = 1; i <= 20; i++) ring.push(i * 10, row([30 + i, 0, 90, 0, 90, 0]));
    expect(feed.update()).toBe(true);
    expect(feed.samples).toBe(21);
    const out = new Float32Array(feed.trail.capacity * 3);
    expect(feed.trail.copyInto(out)).toBe(21);
    // The newest point of the path is the flange drawn.
    const moved = originOf(feed.frames[6] as Float64Array);
    expect(out[20 * 3]).toBeCloseTo(moved[0], 5);
    expect(moved[0]).not.toBeCloseTo((tcp[0] ?? Number.NaN) / 1000, 3);
  });

  it("skips frames without joint values and keeps the last pose", () => {
    const ring = new SampleRing(100, channels.channelCount);
    const feed = new RobotPoseFeed(new ArmChain(ARMS.M0609), ring, channels);
    ring.push(0, row([0, 0, 90, 0, 90, 0]));
    ring.push(10, new Float64Array(channels.channelCount).fill(Number.NaN));
    expect(feed.update()).toBe(true);
    expect(feed.hasPose).toBe(true);
    expect(originOf(feed.frames[6] as Float64Array)[2]).toBeCloseTo(0.1345 + 0.411 - 0.121, 9);
  });

  it("after a long pause reads only what the path still shows", () => {
    const ring = new SampleRing(10_000, channels.channelCount);
    const feed = new RobotPoseFeed(new ArmChain(ARMS.M1013), ring, channels, 1000, 100);
    for (let i = 0; i < 5000; i++) ring.push(i * 10, row([i % 90, 0, 90, 0, 90, 0]));
    feed.update();
    expect(feed.samples).toBeLessThanOrEqual(101);
  });
});
