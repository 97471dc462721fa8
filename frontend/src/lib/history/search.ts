/**
 * Layer: searching the service's logs (docs/api.md "Searching the logs"): a text and a time range
 * as the query of `GET /api/v1/events` (and the audit trail and the alarm history, which take the
 * same `q`, `from`, `to`), a page of it and its CSV link. Times are what a `datetime-local` input
 * holds ("2026-11-27T12:00"): the service reads a time without an offset as its own local time,
 * the site's. No React.
 */
import { API, errorReason, type JsonClient, type PageAnswer } from "../api/api";
import type { EventKind, EventPage } from "../api/protocol";

export interface SearchFields {
  readonly text: string;
  /** A `datetime-local` value or "" (no bound). */
  readonly from: string;
  readonly to: string;
}

export const NO_SEARCH: SearchFields = { text: "", from: "", to: "" };

export interface SearchQuery {
  readonly q?: string;
  readonly from?: string;
  readonly to?: string;
}

/** The query parameters of `fields`: only those given, the text trimmed. */
export function searchQuery(fields: SearchFields): SearchQuery {
  const text = fields.text.trim();
  return {
    ...(text === "" ? {} : { q: text }),
    ...(fields.from === "" ? {} : { from: fields.from }),
    ...(fields.to === "" ? {} : { to: fields.to }),
  };
}

/** Whether `fields` asks for anything (else the newest rows are shown as they come). */
export function isSearching(fields: SearchFields): boolean {
  return Object.keys(searchQuery(fields)).length > 0;
}

/** A page of the robot's events that match, newest first. */
export async function searchEvents(
  client: JsonClient,
  robot: string,
  kind: EventKind | null,
  fields: SearchFields,
  limit: number,
  offset: number,
): Promise<PageAnswer<EventPage>> {
  const query = { robot, limit, offset, ...searchQuery(fields), ...(kind === null ? {} : { kind }) };
  return pageAnswer(await client.GET("/api/v1/events", { params: { query } }));
}

/** An openapi-fetch answer as a page, or the status and the service's reason. */
export function pageAnswer<T>(result: { readonly data?: T; readonly error?: unknown; readonly response: Response }): PageAnswer<T> {
  if (result.data !== undefined && result.response.status === 200) return { ok: true, page: result.data };
  const status = result.response.status;
  return { ok: false, status, reason: errorReason({ status, body: result.error ?? null }) };
}

/** The CSV of every matching event of the robot (a download link). */
export function searchEventsCsvUrl(robot: string, kind: EventKind | null, fields: SearchFields): string {
  const q = new URLSearchParams({ robot, format: "csv", limit: "100000", ...searchQuery(fields) });
  if (kind !== null) q.set("kind", kind);
  return `${API}/events?${q.toString()}`;
}

/** "41–60 of 75" for a page at `offset` of `shown` rows. */
export function pageWords(offset: number, shown: number, total: number): string {
  if (total === 0 || shown === 0) return `0 of ${total}`;
  return `${offset + 1}–${offset + shown} of ${total}`;
}
