/**
 * The kiosk's cycle times (lib/kiosk/cyclesTile.ts) for its cycle tile, asked for only when the URL
 * shows that tile, every `CYCLE_TILE_REFRESH_MS`; the shift's count from the start of the shift in
 * progress (`shiftStarts`, the service's setting).
 */
import { useEffect, useState } from "react";
import { CYCLE_TILE_REFRESH_MS, DEFAULT_SHIFT_STARTS, NO_CYCLE_TIMES, fetchCycleTimes, shiftStart_ms, type CycleTimes } from "../lib/kiosk/cyclesTile";

export function useKioskCycleTimes(robot: string | null, token: string | null, shown: boolean, shiftStarts: readonly string[] = DEFAULT_SHIFT_STARTS): CycleTimes {
  const startsKey = shiftStarts.join(",");
  const [times, setTimes] = useState<CycleTimes>(NO_CYCLE_TIMES);
  useEffect(() => {
    if (robot === null || !shown) return;
    let cancelled = false;
    const starts = startsKey.split(",");
    const load = () =>
      fetchCycleTimes(robot, token, shiftStart_ms(Date.now(), starts))
        .then((t) => {
          if (!cancelled) setTimes(t);
        })
        .catch(() => undefined);
    void load();
    const timer = setInterval(() => void load(), CYCLE_TILE_REFRESH_MS);
    return () => {
      cancelled = true;
      clearInterval(timer);
    };
  }, [robot, token, shown, startsKey]);
  return times;
}
