import { describe, expect, it } from "vitest";
import { ARMS } from "../../generated/arms";
import { ArmChain, originOf } from "./armKinematics";
import { ChannelMap, JOINT_PLOTS } from "../plots/plots";
import { SampleRing } from "../stream/ringBuffer";
import { pathLength, RobotPoseFeed, TcpTrail } from "./robotPose";

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

describe("pathLength", () => {
  it("adds the straight segments between the points given, and is 0 for one point or none", () => {
    const xyz = new Float32Array([0, 0, 0, 3, 4, 0, 3, 4, 12, 99, 99, 99]);
    expect(pathLength(xyz, 3)).toBeCloseTo(17, 6); // 5 + 12, the fourth point not counted
    expect(pathLength(xyz, 2)).toBeCloseTo(5, 6);
    expect(pathLength(xyz, 1)).toBe(0);
    expect(pathLength(xyz, 0)).toBe(0);
  });

  it("is 0 for a flange that stands still", () => {
    expect(pathLength(new Float32Array([0.5, 0.2, 0.7, 0.5, 0.2, 0.7, 0.5, 0.2, 0.7]), 3)).toBe(0);
  });
});

describe("RobotPoseFeed", () => {
  const channels = new ChannelMap(JOINT_PLOTS);
  const row = (q: readonly number[]) => {
    const r = new Float64Array(channels.channelCount).fill(Number.NaN);
    q.forEach((v, i) => (r[channels.channelOf("joint_position", i)] = v));
    return r;
  };
  const tcpOf = (feed: RobotPoseFeed) => originOf(feed.frames[6] as Float64Array).map((v) => v * 1000);

  it("draws the arm by its kinematics and traces the flange", () => {
    const ring = new SampleRing(1000, channels.channelCount);
    const feed = new RobotPoseFeed(new ArmChain(ARMS.M1013), ring, channels, 1000, 100);
    expect(feed.update()).toBe(false);
    expect(feed.poseAt(0)).toBe(false);
    expect(feed.hasPose).toBe(false);
    ring.push(0, row([30, 0, 90, 0, 90, 0]));
    expect(feed.update()).toBe(true);
    expect(feed.poseAt(0)).toBe(true);
    const tcp = tcpOf(feed);
    expect(tcp[0]).toBeCloseTo(466.9, 1);
    expect(tcp[1]).toBeCloseTo(309.4, 1);
    expect(tcp[2]).toBeCloseTo(651.5, 1);
    expect(feed.update()).toBe(false); // nothing new
    for (let i = 1; i <= 20; i++) ring.push(i * 10, row([30 + i, 0, 90, 0, 90, 0]));
    expect(feed.update()).toBe(true);
    expect(feed.samples).toBe(21);
    const out = new Float32Array(feed.trail.capacity * 3);
    expect(feed.trail.copyInto(out)).toBe(21);
  });

  it("plays the pose back behind the newest sample, interpolated, moving every frame", () => {
    const ring = new SampleRing(1000, channels.channelCount);
    const feed = new RobotPoseFeed(new ArmChain(ARMS.M1013), ring, channels, 1000, 100, 100);
    // A batch of 5 frames 10 ms apart: J1 from 0 to 40 degrees.
    for (let i = 0; i <= 4; i++) ring.push(1000 + i * 10, row([i * 10, 0, 90, 0, 90, 0]));
    feed.update();
    const chain = new ArmChain(ARMS.M1013);
    const at = (j1: number) => chain.tcpPosition_mm([j1, 0, 90, 0, 90, 0]);
    expect(feed.poseAt(5000)).toBe(true); // starts 100 ms behind the newest (t = 940): J1 = 0
    expect(tcpOf(feed)[1]).toBeCloseTo(at(0)[1], 6);
    // Another batch arrives; the browser's clock moves 65 ms: t = 1005, halfway from 0 to 10.
    for (let i = 5; i <= 9; i++) ring.push(1000 + i * 10, row([i * 10, 0, 90, 0, 90, 0]));
    feed.update();
    expect(feed.poseAt(5065)).toBe(true);
    expect(tcpOf(feed)[1]).toBeCloseTo(at(5)[1], 6);
    // Every animation frame moves it, without new data.
    expect(feed.poseAt(5081)).toBe(true);
    expect(tcpOf(feed)[1]).toBeCloseTo(at(21)[1], 6);
    // The joint angles drawn are the interpolated ones, whatever the ring read since.
    expect(feed.drawn_deg[0]).toBeCloseTo(21, 9);
    expect(Array.from(feed.drawn_deg.subarray(1))).toEqual([0, 90, 0, 90, 0]);
    // The same moment again: nothing to draw.
    expect(feed.poseAt(5081)).toBe(false);
    feed.update(); // reads nothing new, changes nothing drawn
    expect(feed.drawn_deg[0]).toBeCloseTo(21, 9);
    // It never runs ahead of the data: held at the newest sample.
    expect(feed.poseAt(9000)).toBe(true);
    expect(tcpOf(feed)[1]).toBeCloseTo(at(90)[1], 6);
    // The path drawn ends at the flange drawn.
    const out = new Float32Array((feed.trail.capacity + 1) * 3);
    const n = feed.trailInto(out);
    expect(out[(n - 1) * 3 + 1]! * 1000).toBeCloseTo(at(90)[1], 3);
  });

  it("catches up after a stall instead of lagging ever more", () => {
    const ring = new SampleRing(10_000, channels.channelCount);
    const feed = new RobotPoseFeed(new ArmChain(ARMS.M1013), ring, channels, 1000, 100, 100);
    ring.push(0, row([0, 0, 90, 0, 90, 0]));
    feed.poseAt(0);
    for (let i = 1; i <= 500; i++) ring.push(i * 10, row([i / 10, 0, 90, 0, 90, 0])); // 5 s later
    feed.update();
    feed.poseAt(16); // the browser's clock moved 16 ms only (the tab was hidden)
    const chain = new ArmChain(ARMS.M1013);
    expect(tcpOf(feed)[1]).toBeCloseTo(chain.tcpPosition_mm([49, 0, 90, 0, 90, 0])[1], 6); // t = 4900
  });

  it("skips frames without joint values and keeps the last pose", () => {
    const ring = new SampleRing(100, channels.channelCount);
    const feed = new RobotPoseFeed(new ArmChain(ARMS.M0609), ring, channels, 5000, 100, 0);
    ring.push(0, row([0, 0, 90, 0, 90, 0]));
    feed.update();
    expect(feed.poseAt(0)).toBe(true);
    ring.push(10, new Float64Array(channels.channelCount).fill(Number.NaN));
    feed.update();
    expect(feed.poseAt(10)).toBe(false);
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
