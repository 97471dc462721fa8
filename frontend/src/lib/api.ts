/**
 * Layer: REST calls of the panel (docs/api.md). Uses fetch with the session cookie; no React.
 *
 * Only the commissioning panel imports this module: the kiosk reads the WebSocket alone, and a
 * test checks that its import graph never reaches this file.
 */
import type { CommandPatch } from "../generated/layout";
import type { AuditItem, CommandState, ControlStatus, EventItem, Page, User } from "./protocol";
import type { HttpAnswer } from "./writes";

export const API = "/api/v1";

async function request(method: string, path: string, body?: unknown): Promise<HttpAnswer> {
  const init: RequestInit = { method, credentials: "same-origin", headers: {} };
  if (body !== undefined) {
    init.body = JSON.stringify(body);
    init.headers = { "Content-Type": "application/json" };
  }
  const response = await fetch(`${API}${path}`, init);
  let parsed: unknown = null;
  const text = await response.text();
  if (text !== "") {
    try {
      parsed = JSON.parse(text);
    } catch {
      parsed = { detail: text };
    }
  }
  return { status: response.status, body: parsed };
}

/** Reason text of an error answer, for showing next to the control that caused it. */
export function errorReason(answer: HttpAnswer): string {
  const body = answer.body as { detail?: unknown } | null;
  const detail = body?.detail;
  if (typeof detail === "string") return detail;
  if (typeof detail === "object" && detail !== null && typeof (detail as { reason?: unknown }).reason === "string") {
    return (detail as { reason: string }).reason;
  }
  return `HTTP ${answer.status}`;
}

export async function getMe(): Promise<User | null> {
  const answer = await request("GET", "/auth/me");
  if (answer.status !== 200) return null;
  return (answer.body as { user: User | null }).user;
}

export async function login(username: string, password: string): Promise<HttpAnswer> {
  return request("POST", "/auth/login", { username, password });
}

export async function logout(): Promise<HttpAnswer> {
  return request("POST", "/auth/logout");
}

export async function takeControl(): Promise<HttpAnswer> {
  return request("POST", "/control/take");
}

export async function releaseControl(): Promise<HttpAnswer> {
  return request("POST", "/control/release");
}

export function controlOf(answer: HttpAnswer): ControlStatus | null {
  const body = answer.body as ControlStatus | null;
  return answer.status === 200 && body !== null && "holder" in body ? body : null;
}

export async function getCommand(): Promise<CommandState | null> {
  const answer = await request("GET", "/command");
  return answer.status === 200 ? (answer.body as CommandState) : null;
}

export async function patchCommand(patch: CommandPatch): Promise<HttpAnswer> {
  return request("PATCH", "/command", patch);
}

export async function getEvents(kind: string | null, limit: number, offset: number): Promise<HttpAnswer> {
  return request("GET", `/events?${eventsQuery(kind, limit, offset)}`);
}

export async function getAudit(limit: number, offset: number): Promise<HttpAnswer> {
  return request("GET", `/audit?limit=${limit}&offset=${offset}`);
}

function eventsQuery(kind: string | null, limit: number, offset: number): string {
  const q = new URLSearchParams({ limit: String(limit), offset: String(offset) });
  if (kind !== null && kind !== "") q.set("kind", kind);
  return q.toString();
}

/** CSV export links (the browser downloads them with the session cookie). */
export function eventsCsvUrl(kind: string | null): string {
  const q = new URLSearchParams({ format: "csv", limit: "100000" });
  if (kind !== null && kind !== "") q.set("kind", kind);
  return `${API}/events?${q.toString()}`;
}

export function auditCsvUrl(): string {
  return `${API}/audit?format=csv&limit=100000`;
}

export type { AuditItem, EventItem, Page };
