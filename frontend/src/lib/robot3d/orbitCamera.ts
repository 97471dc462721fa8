/**
 * Layer: the 3D view's camera rules, pure (no three.js, no DOM, no React).
 *
 * The camera orbits a target point in the robot's base frame, z up: azimuth about z from the x
 * axis, elevation above the x-y plane, distance from the target. The view's buttons and keys
 * turn the orbit by fixed steps and zoom by a fixed factor, within the same limits the mouse's
 * orbit control keeps (lib/robot3d/robotScene3d.ts sets those from `orbitLimits`), and report the camera
 * as rounded numbers for the page's data attributes (tests read them, docs/architecture.md
 * "3D view").
 */

export interface Point3 {
  x: number;
  y: number;
  z: number;
}

export interface Orbit {
  readonly azimuth_rad: number;
  readonly elevation_rad: number;
  readonly distance_m: number;
}

export interface OrbitLimits {
  readonly minDistance_m: number;
  readonly maxDistance_m: number;
  /** Highest and lowest elevation: short of straight up or down, where the azimuth is lost. */
  readonly maxElevation_rad: number;
  readonly minElevation_rad: number;
}

/** What a button or a key does to the camera. */
export type CameraAction =
  | "rotate-left"
  | "rotate-right"
  | "rotate-up"
  | "rotate-down"
  | "zoom-in"
  | "zoom-out"
  | "reset";

/** One press turns the view by this much. */
export const ROTATE_STEP_DEG = 15;
/** One press brings the camera this many times closer (zoom in) or further (zoom out). */
export const ZOOM_STEP_FACTOR = 1.25;

const DEG = Math.PI / 180;

/** The limits for an arm that reaches `reach_m`: from close to its flange to the whole cell. */
export function orbitLimits(reach_m: number): OrbitLimits {
  return {
    minDistance_m: 0.3 * reach_m,
    maxDistance_m: 8 * reach_m,
    maxElevation_rad: 89 * DEG,
    minElevation_rad: -89 * DEG,
  };
}

/** The orbit of a camera at `position` looking at `target`. */
export function orbitOf(position: Point3, target: Point3): Orbit {
  const dx = position.x - target.x;
  const dy = position.y - target.y;
  const dz = position.z - target.z;
  const horizontal = Math.hypot(dx, dy);
  return {
    azimuth_rad: Math.atan2(dy, dx),
    elevation_rad: Math.atan2(dz, horizontal),
    distance_m: Math.hypot(horizontal, dz),
  };
}

/** The camera's position for `orbit` around `target`, into `out` (returned). */
export function positionOf(orbit: Orbit, target: Point3, out: Point3): Point3 {
  const horizontal = orbit.distance_m * Math.cos(orbit.elevation_rad);
  out.x = target.x + horizontal * Math.cos(orbit.azimuth_rad);
  out.y = target.y + horizontal * Math.sin(orbit.azimuth_rad);
  out.z = target.z + orbit.distance_m * Math.sin(orbit.elevation_rad);
  return out;
}

/** An angle in (−π, π]. */
function wrap(angle_rad: number): number {
  const turned = angle_rad - 2 * Math.PI * Math.floor((angle_rad + Math.PI) / (2 * Math.PI));
  return turned === -Math.PI ? Math.PI : turned;
}

/**
 * The orbit after one press of `action` ("reset" is the view's own: it leaves the orbit as is).
 * Left and right turn the robot on screen as a drag the same way does (turning left moves the
 * camera towards the screen's right, so its azimuth grows); up and down view it from higher or
 * lower; zoom in and out bring the camera closer or further, each within `limits`.
 */
export function stepOrbit(orbit: Orbit, action: CameraAction, limits: OrbitLimits): Orbit {
  const clampElevation = (e: number) => Math.min(limits.maxElevation_rad, Math.max(limits.minElevation_rad, e));
  const clampDistance = (d: number) => Math.min(limits.maxDistance_m, Math.max(limits.minDistance_m, d));
  const step = ROTATE_STEP_DEG * DEG;
  switch (action) {
    case "rotate-left":
      return { ...orbit, azimuth_rad: wrap(orbit.azimuth_rad + step) };
    case "rotate-right":
      return { ...orbit, azimuth_rad: wrap(orbit.azimuth_rad - step) };
    case "rotate-up":
      return { ...orbit, elevation_rad: clampElevation(orbit.elevation_rad + step) };
    case "rotate-down":
      return { ...orbit, elevation_rad: clampElevation(orbit.elevation_rad - step) };
    case "zoom-in":
      return { ...orbit, distance_m: clampDistance(orbit.distance_m / ZOOM_STEP_FACTOR) };
    case "zoom-out":
      return { ...orbit, distance_m: clampDistance(orbit.distance_m * ZOOM_STEP_FACTOR) };
    case "reset":
      return orbit;
  }
}

/**
 * The action of a key pressed on the focused view (`KeyboardEvent.key`), or null: arrows
 * rotate, + and − zoom (= and _ too, the same keys without Shift; the keypad's send + and −),
 * 0 and Home reset. A key with Ctrl, Alt or Meta is the browser's (Ctrl + zooms the page).
 */
export function actionOfKey(key: string, modifiers: { ctrl?: boolean; alt?: boolean; meta?: boolean } = {}): CameraAction | null {
  if (modifiers.ctrl === true || modifiers.alt === true || modifiers.meta === true) return null;
  switch (key) {
    case "ArrowLeft":
      return "rotate-left";
    case "ArrowRight":
      return "rotate-right";
    case "ArrowUp":
      return "rotate-up";
    case "ArrowDown":
      return "rotate-down";
    case "+":
    case "=":
      return "zoom-in";
    case "-":
    case "_":
    case "\u2212":
      return "zoom-out";
    case "0":
    case "Home":
      return "reset";
    default:
      return null;
  }
}

/** The camera as the page shows it: whole degrees and millimetres. */
export interface CameraReadout {
  readonly azimuth_deg: number;
  readonly elevation_deg: number;
  readonly distance_mm: number;
}

export function cameraReadout(orbit: Orbit): CameraReadout {
  // + 0 turns a rounded −0 into 0, so the attribute never reads "-0".
  return {
    azimuth_deg: Math.round(orbit.azimuth_rad / DEG) + 0,
    elevation_deg: Math.round(orbit.elevation_rad / DEG) + 0,
    distance_mm: Math.round(orbit.distance_m * 1000) + 0,
  };
}
