/**
 * The kiosk's "maintenance due" mark (lib/health/maintenanceMark.ts): the robot's health read
 * with a plain GET every `MAINTENANCE_REFRESH_MS` once the stream has named the robot. An answer
 * that does not come leaves the last mark (a kiosk does not flicker on one lost request).
 */
import { useEffect, useState } from "react";
import { MAINTENANCE_REFRESH_MS, NO_MARK, fetchHealth, maintenanceMark, type MaintenanceMark } from "../lib/health/maintenanceMark";

export function useKioskMaintenance(robot: string | null, token: string | null): MaintenanceMark {
  const [mark, setMark] = useState<MaintenanceMark>(NO_MARK);
  useEffect(() => {
    if (robot === null) return;
    let cancelled = false;
    const load = () =>
      fetchHealth(robot, token)
        .then((answer) => {
          if (!cancelled && answer !== null) setMark(maintenanceMark(answer));
        })
        .catch(() => undefined);
    void load();
    const timer = setInterval(() => void load(), MAINTENANCE_REFRESH_MS);
    return () => {
      cancelled = true;
      clearInterval(timer);
    };
  }, [robot, token]);
  return mark;
}
