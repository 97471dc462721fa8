import { describe, expect, it } from "vitest";
import {
  actionOfKey,
  cameraReadout,
  orbitLimits,
  orbitOf,
  positionOf,
  ROTATE_STEP_DEG,
  stepOrbit,
  ZOOM_STEP_FACTOR,
  type CameraAction,
  type Orbit,
  type Point3,
} from "./orbitCamera";

const DEG = Math.PI / 180;
const target: Point3 = { x: 0, y: 0, z: 0.4 };
const limits = orbitLimits(1.3);
const home: Orbit = orbitOf({ x: 1.365, y: -1.105, z: 0.91 }, target);

describe("orbitOf and positionOf", () => {
  it("measure azimuth from x about z, elevation above x-y, distance from the target", () => {
    const o = orbitOf({ x: 0, y: 2, z: 0.4 }, target);
    expect(o.azimuth_rad).toBeCloseTo(Math.PI / 2, 12);
    expect(o.elevation_rad).toBeCloseTo(0, 12);
    expect(o.distance_m).toBeCloseTo(2, 12);
    const above = orbitOf({ x: 1, y: 0, z: 1.4 }, target);
    expect(above.elevation_rad).toBeCloseTo(Math.PI / 4, 12);
    expect(above.distance_m).toBeCloseTo(Math.SQRT2, 12);
  });

  it("are each other's inverse", () => {
    const out = { x: 0, y: 0, z: 0 };
    for (const p of [
      { x: 1.365, y: -1.105, z: 0.91 },
      { x: -0.2, y: 0.7, z: -0.3 },
      { x: -1, y: -0.01, z: 2 },
    ]) {
      const back = positionOf(orbitOf(p, target), target, out);
      expect(back.x).toBeCloseTo(p.x, 12);
      expect(back.y).toBeCloseTo(p.y, 12);
      expect(back.z).toBeCloseTo(p.z, 12);
    }
  });
});

describe("stepOrbit", () => {
  it("turns left by growing the azimuth one step, right by shrinking it, the rest unchanged", () => {
    const left = stepOrbit(home, "rotate-left", limits);
    expect(left.azimuth_rad - home.azimuth_rad).toBeCloseTo(ROTATE_STEP_DEG * DEG, 12);
    expect(left.elevation_rad).toBe(home.elevation_rad);
    expect(left.distance_m).toBe(home.distance_m);
    const back = stepOrbit(left, "rotate-right", limits);
    expect(back.azimuth_rad).toBeCloseTo(home.azimuth_rad, 12);
  });

  it("keeps the azimuth in (−180°, 180°] all the way round", () => {
    let o = home;
    for (let i = 0; i < 360 / ROTATE_STEP_DEG; i++) {
      o = stepOrbit(o, "rotate-left", limits);
      expect(o.azimuth_rad).toBeGreaterThan(-Math.PI);
      expect(o.azimuth_rad).toBeLessThanOrEqual(Math.PI);
    }
    expect(o.azimuth_rad).toBeCloseTo(home.azimuth_rad, 9); // a whole turn: where it began
  });

  it("views from higher and lower, never past straight up or down", () => {
    expect(stepOrbit(home, "rotate-up", limits).elevation_rad - home.elevation_rad).toBeCloseTo(ROTATE_STEP_DEG * DEG, 12);
    let o = home;
    for (let i = 0; i < 20; i++) o = stepOrbit(o, "rotate-up", limits);
    expect(o.elevation_rad).toBe(limits.maxElevation_rad);
    for (let i = 0; i < 40; i++) o = stepOrbit(o, "rotate-down", limits);
    expect(o.elevation_rad).toBe(limits.minElevation_rad);
    expect(o.azimuth_rad).toBe(home.azimuth_rad);
  });

  it("zooms by the step factor within the distance limits", () => {
    const closer = stepOrbit(home, "zoom-in", limits);
    expect(closer.distance_m).toBeCloseTo(home.distance_m / ZOOM_STEP_FACTOR, 12);
    expect(stepOrbit(closer, "zoom-out", limits).distance_m).toBeCloseTo(home.distance_m, 12);
    let o = home;
    for (let i = 0; i < 50; i++) o = stepOrbit(o, "zoom-in", limits);
    expect(o.distance_m).toBe(limits.minDistance_m);
    for (let i = 0; i < 50; i++) o = stepOrbit(o, "zoom-out", limits);
    expect(o.distance_m).toBe(limits.maxDistance_m);
  });

  it("leaves the orbit to the view on reset", () => {
    expect(stepOrbit(home, "reset", limits)).toBe(home);
  });
});

describe("actionOfKey", () => {
  it("maps arrows, plus and minus, 0 and Home", () => {
    const expected: Record<string, CameraAction> = {
      ArrowLeft: "rotate-left",
      ArrowRight: "rotate-right",
      ArrowUp: "rotate-up",
      ArrowDown: "rotate-down",
      "+": "zoom-in",
      "=": "zoom-in",
      "-": "zoom-out",
      _: "zoom-out",
      "0": "reset",
      Home: "reset",
    };
    for (const [key, action] of Object.entries(expected)) expect(actionOfKey(key)).toBe(action);
  });

  it("leaves every other key, and any key with Ctrl, Alt or Meta, to the browser", () => {
    for (const key of ["Tab", "Enter", " ", "Escape", "a", "PageDown"]) expect(actionOfKey(key)).toBeNull();
    expect(actionOfKey("+", { ctrl: true })).toBeNull();
    expect(actionOfKey("-", { meta: true })).toBeNull();
    expect(actionOfKey("ArrowLeft", { alt: true })).toBeNull();
  });
});

describe("cameraReadout", () => {
  it("rounds to whole degrees and millimetres, never −0", () => {
    const r = cameraReadout({ azimuth_rad: -38.99 * DEG, elevation_rad: -0.2 * DEG, distance_m: 1.73449 });
    expect(r).toEqual({ azimuth_deg: -39, elevation_deg: 0, distance_mm: 1734 });
    expect(Object.is(r.elevation_deg, -0)).toBe(false);
  });
});
