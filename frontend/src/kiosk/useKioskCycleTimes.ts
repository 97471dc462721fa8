/**
 * The kiosk's cycle times (lib/cyclesTile.ts) for its cycle-time tile, asked for only when the
 * URL shows that tile, every `CYCLE_TILE_REFRESH_MS`.
 */
import { useEffect, useState } from "react";
import { CYCLE_TILE_REFRESH_MS, NO_CYCLE_TIMES, fetchCycleTimes, type CycleTimes } from "../lib/cyclesTile";

export function useKioskCycleTimes(robot: string | null, token: string | null, shown: boolean): CycleTimes {
  const [times, setTimes] = useState<CycleTimes>(NO_CYCLE_TIMES);
  useEffect(() => {
    if (robot === null || !shown) return;
    let cancelled = false;
    const load = () =>
      fetchCycleTimes(robot, token)
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
  }, [robot, token, shown]);
  return times;
}
