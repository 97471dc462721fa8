/**
 * Layer: pure routing rules (no React, no DOM): which face a path shows, which robot a URL
 * names, and the links between the faces. The selected robot lives in the URL (`?robot=NAME`)
 * so that a link opens the same robot (docs/getting-started.md).
 */

export type Face = "panel" | "kiosk" | "fleet" | "health" | "plant";

/** `/kiosk` is the kiosk, `/fleet` the fleet overview, `/health` a robot's health, anything else the panel. */
export function faceOf(pathname: string): Face {
  if (/^\/kiosk\/?$/.test(pathname)) return "kiosk";
  if (/^\/fleet\/?$/.test(pathname)) return "fleet";
  if (/^\/health\/?$/.test(pathname)) return "health";
  // The plant page: `cobot-hmi plant` serves the same build and sends its `/` here.
  if (/^\/plant\/?$/.test(pathname)) return "plant";
  return "panel";
}

export function isKioskPath(pathname: string): boolean {
  return faceOf(pathname) === "kiosk";
}

/** A robot's name as the service's settings allow it (docs/api.md, robots). */
export const ROBOT_NAME_PATTERN = /^[a-z0-9][a-z0-9_-]{0,31}$/;

/** The robot a URL's query names (`?robot=NAME`), or null when it names none or an invalid one. */
export function robotFromSearch(search: string): string | null {
  const name = new URLSearchParams(search).get("robot");
  return name !== null && ROBOT_NAME_PATTERN.test(name) ? name : null;
}

/** `search` with `?robot=` set to `robot` (null: removed); other parameters are kept. */
export function searchWithRobot(search: string, robot: string | null): string {
  const query = new URLSearchParams(search);
  if (robot === null) query.delete("robot");
  else query.set("robot", robot);
  const text = query.toString();
  return text === "" ? "" : `?${text}`;
}

/**
 * The robot a page shows: the one its URL names when the service knows it, else the service's
 * first (default) robot; null while the list is unknown and the URL names none. A name the
 * service does not know is reported as `unknown`, so the page can say so instead of guessing.
 */
export function chooseRobot(
  wanted: string | null,
  known: readonly string[] | null,
): { readonly robot: string | null; readonly unknown: string | null } {
  if (known === null) return { robot: wanted, unknown: null };
  if (wanted !== null && known.includes(wanted)) return { robot: wanted, unknown: null };
  return { robot: known[0] ?? null, unknown: wanted };
}

export function panelHref(robot: string): string {
  return `/${searchWithRobot("", robot)}`;
}

export function kioskHref(robot: string): string {
  return `/kiosk${searchWithRobot("", robot)}`;
}

/** A robot's health page (issue 40): its joints' verdicts, figures, trends, knocks and baselines. */
export function healthHref(robot: string): string {
  return `/health${searchWithRobot("", robot)}`;
}

export const FLEET_HREF = "/fleet";

/** A range of the past a URL names (`from` and `to`, epoch seconds: the panel opens its plots
 * there, as the plant page's History link asks), or null when it names none or no valid one. */
export function rangeFromSearch(search: string): { readonly from_s: number; readonly to_s: number } | null {
  const query = new URLSearchParams(search);
  const from = query.get("from");
  const to = query.get("to");
  if (from === null || to === null || from.trim() === "" || to.trim() === "") return null;
  const from_s = Number(from);
  const to_s = Number(to);
  return Number.isFinite(from_s) && Number.isFinite(to_s) && to_s > from_s ? { from_s, to_s } : null;
}

/** A robot's recorded frames over `[from_s, to_s]` in its cell's panel (`rangeFromSearch`). */
export function historyHref(robot: string, from_s: number, to_s: number): string {
  return `/?${new URLSearchParams({ robot, from: from_s.toFixed(0), to: to_s.toFixed(0) }).toString()}`;
}
