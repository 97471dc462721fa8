/**
 * The kiosk's robot model for its 3D view: asked once the stream's hello has named the robot,
 * again every 10 s until the service knows it (it reads the identity after connecting).
 */
import { useEffect, useState } from "react";
import { fetchRobotModel } from "../lib/robot3d/robotModel";

const RETRY_MS = 10_000;

export function useRobotModel(robot: string | null, token: string | null): string | null {
  const [model, setModel] = useState<string | null>(null);
  useEffect(() => {
    if (robot === null) return;
    let cancelled = false;
    let timer: ReturnType<typeof setTimeout> | null = null;
    const load = () => {
      fetchRobotModel(robot, token)
        .then((found) => {
          if (cancelled) return;
          if (found !== null) setModel(found);
          else timer = setTimeout(load, RETRY_MS);
        })
        .catch(() => {
          if (!cancelled) timer = setTimeout(load, RETRY_MS);
        });
    };
    load();
    return () => {
      cancelled = true;
      if (timer !== null) clearTimeout(timer);
    };
  }, [robot, token]);
  return model;
}
