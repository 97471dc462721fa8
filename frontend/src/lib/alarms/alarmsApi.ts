/**
 * Layer: the panel's REST calls for alarms and tag names (docs/api.md "Alarms", "Tag names"),
 * over the typed client of `lib/api/api.ts`. No React. The kiosk never imports this module (it
 * reaches `lib/api/api.ts`, which its import-graph test forbids): the kiosk's banner reads the
 * stream only.
 */
import { API, api, errorReason, type JsonClient, type PageAnswer } from "../api/api";
import type { Alarm, AlarmHistoryRow, AlarmPriority } from "./alarms";
import type { components } from "../../generated/api";
import type { HttpAnswer } from "../writes/writes";

type Schemas = components["schemas"];
export type AlarmHistoryPage = Schemas["AlarmHistoryPage"];
export type TagList = Schemas["TagList"];
export type TagPoint = Schemas["TagPoint"];
export type AlarmAckManyAnswer = Schemas["AlarmAckManyAnswer"];

const JSON_CONTENT = { "Content-Type": "application/json" } as const;

/** What an alarm action answered: the alarm as it is now, or why not. */
export type AlarmActionAnswer = { readonly ok: true; readonly alarm: Alarm; readonly changed: boolean } | { readonly ok: false; readonly reason: string };

interface Fetched<T> {
  readonly data?: T;
  readonly error?: unknown;
  readonly response: Response;
}

function answerOf(result: Fetched<unknown>): HttpAnswer {
  return { status: result.response.status, body: result.data ?? result.error ?? null };
}

function actionOf(result: Fetched<Schemas["AlarmAnswer"]>): AlarmActionAnswer {
  if (result.data !== undefined && result.response.status === 200) return { ok: true, alarm: result.data.alarm, changed: result.data.changed };
  return { ok: false, reason: errorReason(answerOf(result)) };
}

function pageOf<T>(result: Fetched<T>): PageAnswer<T> {
  if (result.data !== undefined && result.response.status === 200) return { ok: true, page: result.data };
  const answer = answerOf(result);
  return { ok: false, status: answer.status, reason: errorReason(answer) };
}

export interface HistoryFilter {
  readonly priority: AlarmPriority | null;
  /** s since the epoch, null: no bound */
  readonly since: number | null;
  readonly until: number | null;
}

function historyQuery(robot: string, filter: HistoryFilter) {
  return {
    robot,
    ...(filter.priority !== null ? { priority: filter.priority } : {}),
    ...(filter.since !== null ? { since: filter.since } : {}),
    ...(filter.until !== null ? { until: filter.until } : {}),
  };
}

export class AlarmsApi {
  constructor(readonly client: JsonClient) {}

  async ack(alarmId: string, comment: string | null): Promise<AlarmActionAnswer> {
    return actionOf(
      await this.client.POST("/api/v1/alarms/{alarm_id}/ack", {
        params: { path: { alarm_id: alarmId } },
        body: comment !== null && comment !== "" ? { comment } : {},
        headers: JSON_CONTENT,
      }),
    );
  }

  /** Acknowledge the alarms named, in one request (the service audits each one). */
  async ackMany(ids: readonly string[], comment: string | null): Promise<PageAnswer<AlarmAckManyAnswer>> {
    const body = { ids: [...ids], ...(comment !== null && comment !== "" ? { comment } : {}) };
    return pageOf(await this.client.POST("/api/v1/alarms/ack", { body, headers: JSON_CONTENT }));
  }

  async shelve(alarmId: string, reason: string, duration_s: number): Promise<AlarmActionAnswer> {
    return actionOf(
      await this.client.POST("/api/v1/alarms/{alarm_id}/shelve", {
        params: { path: { alarm_id: alarmId } },
        body: { reason, duration_s },
      }),
    );
  }

  async unshelve(alarmId: string): Promise<AlarmActionAnswer> {
    return actionOf(
      await this.client.POST("/api/v1/alarms/{alarm_id}/unshelve", { params: { path: { alarm_id: alarmId } }, headers: JSON_CONTENT }),
    );
  }

  async history(robot: string, filter: HistoryFilter, limit: number, offset: number): Promise<PageAnswer<AlarmHistoryPage>> {
    const query = { ...historyQuery(robot, filter), limit, offset };
    return pageOf(await this.client.GET("/api/v1/alarms/history", { params: { query } }));
  }

  async tags(robot: string): Promise<PageAnswer<TagList>> {
    return pageOf(await this.client.GET("/api/v1/robots/{name}/tags", { params: { path: { name: robot } } }));
  }

  async putTags(robot: string, tags: Readonly<Record<string, string>>): Promise<PageAnswer<TagList>> {
    return pageOf(await this.client.PUT("/api/v1/robots/{name}/tags", { params: { path: { name: robot } }, body: { tags: { ...tags } } }));
  }

  async importTags(robot: string, csv: string): Promise<PageAnswer<TagList>> {
    return pageOf(await this.client.POST("/api/v1/robots/{name}/tags/import", { params: { path: { name: robot } }, body: { csv } }));
  }
}

/** The panel's client: the page's REST client (same origin, the session cookie). */
export const alarmsApi = new AlarmsApi(api.client);

/** The whole filtered history as CSV, streamed (no limit: not a page); the browser downloads it
 * with the session cookie. */
export function alarmHistoryCsvUrl(robot: string, filter: HistoryFilter): string {
  const q = new URLSearchParams({ format: "csv" });
  for (const [k, v] of Object.entries(historyQuery(robot, filter))) q.set(k, String(v));
  return `${API}/alarms/history?${q.toString()}`;
}

export function tagsCsvUrl(robot: string): string {
  return `${API}/robots/${encodeURIComponent(robot)}/tags.csv`;
}

export type { AlarmHistoryRow };
