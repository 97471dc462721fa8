/**
 * Layer: the history plot's requests (docs/api.md "History"), over the typed REST client: a
 * decimated range and its events together, both cancelled by one AbortSignal. No React.
 */
import type { JsonClient } from "../api/api";
import { errorReason } from "../api/api";
import type { FetchRange, HistoryEvent } from "../plots/historyView";

export function historyFetcher(client: JsonClient, robot: string, fields: string): FetchRange {
  return async (range, points, signal) => {
    const path = { name: robot };
    const from = range.from_s.toFixed(3);
    const to = range.to_s.toFixed(3);
    const [frames, events] = await Promise.all([
      client.GET("/api/v1/robots/{name}/history", { params: { path, query: { from, to, fields, points } }, signal }),
      client.GET("/api/v1/robots/{name}/history/events", { params: { path, query: { from, to } }, signal }),
    ]);
    if (frames.data === undefined) {
      throw new Error(errorReason({ status: frames.response.status, body: frames.error ?? null }));
    }
    const items: readonly HistoryEvent[] = events.data?.items ?? [];
    return { range, answer: frames.data, events: items };
  };
}
