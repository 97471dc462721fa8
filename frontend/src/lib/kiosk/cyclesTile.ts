/**
 * Layer: the kiosk's cycle tile (`/kiosk?tiles=cycle_time`), as line-side displays show it (issue
 * 38): the robot's last cycle, the mean of its last ten, the cycles of the shift in progress and
 * a mark when the last was slow (docs/operations.md "Cycle timing"). Read with plain GETs as the
 * kiosk reads its tag names (the kiosk has no REST client: it writes nothing); the shifts are the
 * service's `shift_starts` setting (the stream's hello), in the plant's time zone. No React.
 */
import type { components } from "../../generated/api";
import type { FieldInfo, Frame } from "../../generated/layout";
import { siteTimeZone, utcOffset_min } from "../common/dates";

type CyclePage = components["schemas"]["CyclePage"];

/** The tile's name in the kiosk's URL. */
export const CYCLE_TILE_NAME = "cycle_time";
/** The mean is of the newest this many cycles. */
export const CYCLE_TILE_WINDOW = 10;
/** A cycle lasts seconds: asked again this often. */
export const CYCLE_TILE_REFRESH_MS = 2000;
/** The last cycle is slow when it took more than this share of the mean of the last ten. */
export const SLOW_CYCLE_FACTOR = 1.1;
/** The shifts without a word from the service (an older one). */
export const DEFAULT_SHIFT_STARTS: readonly string[] = ["06:00", "14:00", "22:00"];

/** A tile like a frame field's: three cells, two in seconds and a count. */
export const CYCLE_TILE: FieldInfo = {
  name: CYCLE_TILE_NAME,
  offset: -1,
  cip_type: "REAL",
  count: 3,
  first_bit: null,
  bit_count: 0,
  scalar: false,
  value_kind: "float",
  unit: "s",
  group: "Cycle",
  description: "Cycle time",
  channels: ["last", `mean of ${CYCLE_TILE_WINDOW}`, "this shift"],
};

/** Decimals of each of the tile's cells: seconds to a tenth, the count whole. */
export const CYCLE_TILE_DECIMALS: readonly number[] = [1, 1, 0];

/** `[last, mean of ten]` in seconds and the shift's count (null: none yet, no trigger, unreadable). */
export interface CycleTimes {
  readonly last_s: number | null;
  readonly mean_s: number | null;
  readonly shiftCount: number | null;
}

export const NO_CYCLE_TIMES: CycleTimes = { last_s: null, mean_s: null, shiftCount: null };

/** Whether the last cycle was slow: over `SLOW_CYCLE_FACTOR` times the mean of the last ten. */
export function isSlowCycle(times: CycleTimes): boolean {
  return times.last_s !== null && times.mean_s !== null && times.mean_s > 0 && times.last_s > SLOW_CYCLE_FACTOR * times.mean_s;
}

/** "06:00" → 360 (minutes of the day), null for anything else. */
function minutesOfDay(text: string): number | null {
  const m = /^([01]\d|2[0-3]):([0-5]\d)$/.exec(text);
  return m === null ? null : Number(m[1]) * 60 + Number(m[2]);
}

/**
 * When the shift in progress at `now_ms` started (ms since the epoch): the latest of the
 * `starts` (HH:MM in `zone`, the plant's) at or before now, today's or yesterday's.
 */
export function shiftStart_ms(now_ms: number, starts: readonly string[], zone = siteTimeZone()): number {
  const minutes = starts.map(minutesOfDay).filter((m): m is number => m !== null);
  if (minutes.length === 0) return now_ms - 86_400_000;
  const day_ms = 86_400_000;
  const localNow = now_ms + utcOffset_min(now_ms, zone) * 60_000;
  const localMidnight = Math.floor(localNow / day_ms) * day_ms;
  let best = -Infinity;
  for (const back of [0, 1]) {
    for (const m of minutes) {
      const local = localMidnight - back * day_ms + m * 60_000;
      // The local time back to the epoch with the offset at that moment (a DST change between).
      const guess = local - utcOffset_min(local, zone) * 60_000;
      const at = local - utcOffset_min(guess, zone) * 60_000;
      if (at <= now_ms && at > best) best = at;
    }
  }
  return best;
}

async function getCycles(robot: string, token: string | null, query: Record<string, string>): Promise<CyclePage | null> {
  const headers: Record<string, string> = { Accept: "application/json" };
  if (token !== null && token !== "") headers.Authorization = `Bearer ${token}`;
  const url = `/api/v1/robots/${encodeURIComponent(robot)}/cycles?${new URLSearchParams(query).toString()}`;
  const response = await fetch(url, { method: "GET", headers, credentials: "same-origin" });
  return response.ok ? ((await response.json()) as CyclePage) : null;
}

/** The robot's last cycle, the mean of its last ten and the count since `shiftStart`. */
export async function fetchCycleTimes(robot: string, token: string | null, shiftStart: number): Promise<CycleTimes> {
  const [recent, shift] = await Promise.all([
    getCycles(robot, token, { limit: "1", last: String(CYCLE_TILE_WINDOW) }),
    getCycles(robot, token, { limit: "1", last: "1", from: String(shiftStart / 1000) }),
  ]);
  return {
    last_s: recent?.statistics.last_s ?? null,
    mean_s: recent?.statistics.mean_s ?? null,
    shiftCount: shift?.statistics.count ?? null,
  };
}

/** `frame` with the cycle times where the tile reads them (`frame.cycle_time`). */
export function withCycleTimes(frame: Frame | null, times: CycleTimes): Frame | null {
  if (frame === null) return null;
  return { ...frame, [CYCLE_TILE_NAME]: [times.last_s, times.mean_s, times.shiftCount], cycle_time_slow: isSlowCycle(times) } as Frame;
}
