/**
 * Layer: cycle timing in the panel (docs/operations.md "Cycle timing"): the robot's measured
 * cycles and their statistics from `GET /api/v1/robots/{name}/cycles` (the generated types), the
 * histogram of their durations and the figures in words. No React.
 */
import type { components } from "../../generated/api";
import { API, type JsonClient, type PageAnswer } from "../api/api";
import { pageAnswer } from "./search";

export type CyclePage = components["schemas"]["CyclePage"];
export type CycleRow = components["schemas"]["CycleRow"];
export type CycleStatistics = components["schemas"]["CycleStatistics"];

/** The panel's N: mean, min and max are of the newest this many cycles. */
export const CYCLE_WINDOW = 20;
/** The trend and the histogram show at most this many (the newest) cycles. */
export const CYCLES_SHOWN = 500;

/**
 * The robot's newest cycles (the service's default range: all) and their statistics, of whole
 * cycles unless `includeInterrupted` (docs/api.md "Cycle timing").
 */
export async function fetchCycles(
  client: JsonClient,
  robot: string,
  last = CYCLE_WINDOW,
  limit = CYCLES_SHOWN,
  includeInterrupted = false,
): Promise<PageAnswer<CyclePage>> {
  const query = { last, limit, ...(includeInterrupted ? { include_interrupted: true } : {}) };
  return pageAnswer(await client.GET("/api/v1/robots/{name}/cycles", { params: { path: { name: robot }, query } }));
}

/**
 * The cycles the trend and the histogram draw, and the interrupted ones shown apart (a stop, a
 * lost link, the robot out of its running states: one 142 s "cycle" across two e-stops would
 * squash 61 cycles of 8 s into one bar). `include`: every cycle drawn, as the statistics then are.
 */
export function splitCycles(cycles: readonly CycleRow[], include = false): { drawn: CycleRow[]; interrupted: CycleRow[] } {
  const interrupted = cycles.filter((c) => c.interrupted);
  return { drawn: include ? [...cycles] : cycles.filter((c) => !c.interrupted), interrupted };
}

/** "2 interrupted cycles, left out of the statistics" (or "…, included"); "" when there are none. */
export function interruptedWords(statistics: CycleStatistics): string {
  const n = statistics.interrupted;
  if (n === 0) return "";
  const what = n === 1 ? "1 interrupted cycle" : `${n} interrupted cycles`;
  return `${what}, ${statistics.include_interrupted ? "included in" : "left out of"} the statistics`;
}

/** The CSV export of every cycle of the robot (a download link: the session cookie goes along). */
export function cyclesCsvUrl(robot: string): string {
  return `${API}/robots/${encodeURIComponent(robot)}/cycles?${new URLSearchParams({ format: "csv", limit: "100000" }).toString()}`;
}

/** A duration in seconds as the panel shows it: "8.07 s", "—" when there is none. */
export function formatCycle_s(seconds: number | null | undefined): string {
  return seconds === null || seconds === undefined || !Number.isFinite(seconds) ? "—" : `${seconds.toFixed(2)} s`;
}

export interface Histogram {
  /** Each bin's centre, s. */
  readonly centres_s: readonly number[];
  readonly counts: readonly number[];
  readonly width_s: number;
}

/**
 * The durations in `bins` equal bins from their minimum to their maximum (the maximum in the
 * last bin); one bin of 0.1 s around the value when every duration is the same; none when empty.
 */
export function histogram(durations_s: readonly number[], bins = 20): Histogram {
  const finite = durations_s.filter((d) => Number.isFinite(d));
  if (finite.length === 0) return { centres_s: [], counts: [], width_s: 0 };
  const low = Math.min(...finite);
  const high = Math.max(...finite);
  if (high === low) return { centres_s: [low], counts: [finite.length], width_s: 0.1 };
  const n = Math.max(1, Math.floor(bins));
  const width = (high - low) / n;
  const counts = new Array<number>(n).fill(0);
  for (const d of finite) {
    const i = Math.min(n - 1, Math.floor((d - low) / width));
    counts[i] = (counts[i] ?? 0) + 1;
  }
  return { centres_s: counts.map((_, i) => low + (i + 0.5) * width), counts, width_s: width };
}

/** The kiosk's and the panel's two figures: the last cycle and the mean of the newest N. */
export function cycleFigures(statistics: CycleStatistics): { readonly last: string; readonly mean: string } {
  return { last: formatCycle_s(statistics.last_s), mean: formatCycle_s(statistics.mean_s) };
}
