/**
 * Layer: React glue for the live pipeline (read-only: no writes, no REST).
 * Shared by the panel and the kiosk.
 */
import { createContext, useContext, useSyncExternalStore } from "react";
import type { LiveSnapshot } from "../lib/stream/liveData";
import type { LiveRuntime } from "../lib/stream/runtime";

export const RuntimeContext = createContext<LiveRuntime | null>(null);

export function useRuntime(): LiveRuntime {
  const runtime = useContext(RuntimeContext);
  if (runtime === null) throw new Error("RuntimeContext missing");
  return runtime;
}

/** The live snapshot, re-rendering at most at the store's publish rate. */
export function useLive(): LiveSnapshot {
  const { live } = useRuntime();
  return useSyncExternalStore(live.subscribe, live.getSnapshot);
}
