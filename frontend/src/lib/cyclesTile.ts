/**
 * Layer: the kiosk's cycle-time tile (`/kiosk?tiles=cycle_time`): the robot's last cycle and the
 * mean of its last 20 (docs/operations.md "Cycle timing"), read with a plain GET as the kiosk
 * reads its tag names (the kiosk has no REST client: it writes nothing), shown as a tile beside
 * the frame's numbers (lib/kioskTiles.ts). No React.
 */
import type { components } from "../generated/api";
import type { FieldInfo, Frame } from "../generated/layout";

type CyclePage = components["schemas"]["CyclePage"];

/** The tile's name in the kiosk's URL. */
export const CYCLE_TILE_NAME = "cycle_time";
/** The mean is of the newest this many cycles. */
export const CYCLE_TILE_WINDOW = 20;
/** A cycle lasts seconds: asked again this often. */
export const CYCLE_TILE_REFRESH_MS = 2000;

/** A tile like a frame field's: two cells, in seconds. */
export const CYCLE_TILE: FieldInfo = {
  name: CYCLE_TILE_NAME,
  offset: -1,
  cip_type: "REAL",
  count: 2,
  first_bit: null,
  bit_count: 0,
  scalar: false,
  value_kind: "float",
  unit: "s",
  group: "Cycle",
  description: "Cycle time",
  channels: ["last", `mean of ${CYCLE_TILE_WINDOW}`],
};

/** `[last, mean]` in seconds (null: no cycle yet, no trigger, or not readable). */
export type CycleTimes = readonly [number | null, number | null];

export const NO_CYCLE_TIMES: CycleTimes = [null, null];

/** The robot's last cycle and the mean of its last `CYCLE_TILE_WINDOW`. */
export async function fetchCycleTimes(robot: string, token: string | null): Promise<CycleTimes> {
  const headers: Record<string, string> = { Accept: "application/json" };
  if (token !== null && token !== "") headers.Authorization = `Bearer ${token}`;
  const query = new URLSearchParams({ limit: "1", last: String(CYCLE_TILE_WINDOW) });
  const response = await fetch(`/api/v1/robots/${encodeURIComponent(robot)}/cycles?${query.toString()}`, { method: "GET", headers, credentials: "same-origin" });
  if (!response.ok) return NO_CYCLE_TIMES;
  const page = (await response.json()) as CyclePage;
  return [page.statistics.last_s ?? null, page.statistics.mean_s ?? null];
}

/** `frame` with the cycle times where the tile reads them (`frame.cycle_time`). */
export function withCycleTimes(frame: Frame | null, times: CycleTimes): Frame | null {
  if (frame === null) return null;
  return { ...frame, [CYCLE_TILE_NAME]: times } as Frame;
}
