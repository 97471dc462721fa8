import { describe, expect, it } from "vitest";
import { ARMS } from "../../generated/arms";
import { ArmChain, armNameOf, originOf } from "./armKinematics";

describe("arm forward kinematics", () => {
  it("matches the M1013 controller's published check (docs/emulator.md, Reference facts)", () => {
    // joints (30, 0, 90, 0, 90, 0)° → TCP (466.9, 309.4, 651.5) mm
    const [x, y, z] = new ArmChain(ARMS.M1013).tcpPosition_mm([30, 0, 90, 0, 90, 0]);
    expect(x).toBeCloseTo(466.9, 1);
    expect(y).toBeCloseTo(309.4, 1);
    expect(z).toBeCloseTo(651.5, 1);
  });

  it("puts the M1013's first joint on its base at the published height", () => {
    const chain = new ArmChain(ARMS.M1013);
    const frames = chain.newFrames();
    chain.forward([0, 0, 0, 0, 0, 0], frames);
    expect(frames).toHaveLength(7);
    expect(originOf(frames[0] as Float64Array)).toEqual([0, 0, 0]);
    const j1 = originOf(frames[1] as Float64Array);
    expect(j1[2]).toBeCloseTo(0.1525, 9);
  });

  it("draws the M0609 shorter than the M1013 at the same joints", () => {
    const q = [0, 0, 90, 0, 90, 0];
    const big = new ArmChain(ARMS.M1013).tcpPosition_mm(q);
    const small = new ArmChain(ARMS.M0609).tcpPosition_mm(q);
    expect(Math.hypot(...small)).toBeLessThan(Math.hypot(...big));
    // At (0, 0, 90, 0, 90, 0) the upper arm stands up, the forearm lies level and the flange
    // points down: height = J1 z + upper arm (J3 x) − flange (J6 y); for the M1013 that is the
    // published check's 651.5 mm.
    expect(small[2]).toBeCloseTo((0.1345 + 0.411 - 0.121) * 1000, 6);
    expect(big[2]).toBeCloseTo((0.1525 + 0.62 - 0.121) * 1000, 6);
  });

  it("moves the TCP when a joint moves, and keeps a joint's axis through its origin", () => {
    const chain = new ArmChain(ARMS.M1013);
    const a = chain.tcpPosition_mm([0, 0, 90, 0, 90, 0]);
    const b = chain.tcpPosition_mm([10, 0, 90, 0, 90, 0]);
    expect(Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2])).toBeGreaterThan(10);
    // A turn of J1 (about the vertical) keeps the height and the distance from the axis.
    expect(b[2]).toBeCloseTo(a[2], 9);
    expect(Math.hypot(b[0], b[1])).toBeCloseTo(Math.hypot(a[0], a[1]), 9);
  });
});

describe("armNameOf", () => {
  it("reads the arm from the identity's product name", () => {
    expect(armNameOf("Doosan M0609 (emulated)")).toEqual({ name: "M0609", known: true });
    expect(armNameOf("Doosan M1013 (emulated)")).toEqual({ name: "M1013", known: true });
  });

  it("falls back to the default arm, saying so", () => {
    expect(armNameOf(null)).toEqual({ name: "M1013", known: false });
    expect(armNameOf("H2017")).toEqual({ name: "M1013", known: false });
  });
});
