/**
 * Layer: the REST client of the panel and the fleet overview (docs/api.md): openapi-fetch over
 * the types generated from the service's OpenAPI document (`src/generated/api.ts`), so a path,
 * a parameter or a body the service does not have fails to compile. Same-origin fetch with the
 * session cookie; every write carries a JSON content type (the service refuses writes without
 * one, against cross-site forms). No React.
 *
 * The kiosk never imports this module: it reads the WebSocket alone, and a test checks that its
 * import graph never reaches this file.
 */
import createClient, { type Client } from "openapi-fetch";
import type { paths } from "../../generated/api";
import type { CommandPatch } from "../../generated/layout";
import type { RobotsAnswer } from "../fleet/fleet";
import { type AuditPage, type CommandState, type ControlStatus, type EventKind, type EventPage, type User } from "./protocol";
import type { SessionState } from "../writes/sessionIdle";
import type { HttpAnswer } from "../writes/writes";

export const API = "/api/v1";

/** On every POST and PATCH, with or without a body: what tells the service it is no form post. */
const JSON_CONTENT = { "Content-Type": "application/json" } as const;

/** What openapi-fetch gives back, as the status and the parsed body (data or error). */
interface Fetched {
  readonly data?: unknown;
  readonly error?: unknown;
  readonly response: Response;
}

function answerOf(result: Fetched): HttpAnswer {
  return { status: result.response.status, body: result.data ?? result.error ?? null };
}

/**
 * The reason of an error answer, for showing next to the control that caused it: the service's
 * `{"detail": {"reason": …}}`, a plain `{"detail": "…"}`, or the status.
 */
export function errorReason(answer: HttpAnswer): string {
  const body = answer.body as { detail?: unknown } | null;
  const detail = body?.detail;
  if (typeof detail === "string") return detail;
  if (typeof detail === "object" && detail !== null && typeof (detail as { reason?: unknown }).reason === "string") {
    return (detail as { reason: string }).reason;
  }
  return `HTTP ${answer.status}`;
}

export function controlOf(answer: HttpAnswer): ControlStatus | null {
  const body = answer.body as ControlStatus | null;
  return answer.status === 200 && body !== null && typeof body === "object" && "holder" in body ? body : null;
}

/** One page of a log, or why there is none. */
export type PageAnswer<T> = { readonly ok: true; readonly page: T } | { readonly ok: false; readonly status: number; readonly reason: string };

function pageOf<T>(result: Fetched & { data?: T }): PageAnswer<T> {
  if (result.data !== undefined && result.response.status === 200) return { ok: true, page: result.data };
  const answer = answerOf(result);
  return { ok: false, status: answer.status, reason: errorReason(answer) };
}

/** The client reads JSON answers (the logs' CSV is a download link, never fetched here). */
export type JsonClient = Client<paths, "application/json">;

export class HmiApi {
  constructor(readonly client: JsonClient) {}

  async me(): Promise<User | null> {
    const result = await this.client.GET("/api/v1/auth/me");
    return result.data?.user ?? null;
  }

  /** The session as it is (a read: it renews nothing); throws when the service does not answer. */
  async session(): Promise<SessionState> {
    const result = await this.client.GET("/api/v1/auth/me");
    if (result.data === undefined) throw new Error(`HTTP ${result.response.status}`);
    return result.data;
  }

  /**
   * The person acted (a click, a key): the only request of the page, with its writes, that renews
   * the session (the service renews on changing requests, never on reads: lib/writes/sessionIdle.ts).
   * `null`: no session any more (401).
   */
  async activity(): Promise<SessionState | null> {
    const result = await this.client.POST("/api/v1/auth/activity", { headers: JSON_CONTENT });
    if (result.response.status === 401) return null;
    if (result.data === undefined) throw new Error(`HTTP ${result.response.status}`);
    return result.data;
  }

  async login(username: string, password: string): Promise<HttpAnswer> {
    return answerOf(await this.client.POST("/api/v1/auth/login", { body: { username, password } }));
  }

  async logout(): Promise<HttpAnswer> {
    return answerOf(await this.client.POST("/api/v1/auth/logout", { headers: JSON_CONTENT }));
  }

  /** Every robot of the service, in its settings' order (the first is the default robot). */
  async robots(): Promise<RobotsAnswer> {
    const result = await this.client.GET("/api/v1/robots");
    if (result.data !== undefined) return { ok: true, robots: result.data.robots };
    return { ok: false, reason: errorReason(answerOf(result)) };
  }

  async takeControl(robot: string): Promise<HttpAnswer> {
    return answerOf(
      await this.client.POST("/api/v1/robots/{name}/control/take", { params: { path: { name: robot } }, headers: JSON_CONTENT }),
    );
  }

  async releaseControl(robot: string): Promise<HttpAnswer> {
    return answerOf(
      await this.client.POST("/api/v1/robots/{name}/control/release", { params: { path: { name: robot } }, headers: JSON_CONTENT }),
    );
  }

  async command(robot: string): Promise<CommandState | null> {
    const result = await this.client.GET("/api/v1/robots/{name}/command", { params: { path: { name: robot } } });
    return result.data ?? null;
  }

  async patchCommand(robot: string, patch: CommandPatch): Promise<HttpAnswer> {
    return answerOf(
      await this.client.PATCH("/api/v1/robots/{name}/command", { params: { path: { name: robot } }, body: patch }),
    );
  }

  async events(robot: string, kind: EventKind | null, limit: number, offset: number): Promise<PageAnswer<EventPage>> {
    const query = kind === null ? { robot, limit, offset } : { robot, kind, limit, offset };
    return pageOf(await this.client.GET("/api/v1/events", { params: { query } }));
  }

  async audit(robot: string, limit: number, offset: number): Promise<PageAnswer<AuditPage>> {
    return pageOf(await this.client.GET("/api/v1/audit", { params: { query: { robot, limit, offset } } }));
  }
}

/** The page's client: same origin, the session cookie. */
export const api = new HmiApi(createClient<paths, "application/json">({ credentials: "same-origin" }));

/** CSV export links of one robot's log (the browser downloads them with the session cookie). */
export function eventsCsvUrl(robot: string, kind: EventKind | null): string {
  const q = new URLSearchParams({ robot, format: "csv", limit: "100000" });
  if (kind !== null) q.set("kind", kind);
  return `${API}/events?${q.toString()}`;
}

export function auditCsvUrl(robot: string): string {
  return `${API}/audit?${new URLSearchParams({ robot, format: "csv", limit: "100000" }).toString()}`;
}
