/**
 * Layer: the shapes of the backend's REST and WebSocket messages (docs/api.md), and a tolerant
 * parser for WebSocket messages. No React, no DOM, no network.
 *
 * Field names of frames and command images are the layout's (generated types); this module only
 * describes the envelopes around them.
 */
import type { CommandImage, Frame } from "../generated/layout";

export type LinkState = "idle" | "connecting" | "connected" | "lost" | "refused";

export interface ConnectionStatus {
  readonly state: LinkState;
  readonly reason: string | null;
  readonly robot: string;
  readonly mode: "exclusive_owner" | "input_only";
  readonly rpi_ms: number;
  readonly packets_in: number;
  readonly packets_out: number;
  readonly gaps: number;
  readonly duplicates: number;
  readonly late: number;
  readonly interval_mean_ms: number | null;
  readonly interval_p99_ms: number | null;
  readonly interval_max_ms: number | null;
  readonly last_frame_age_s: number | null;
  readonly stale: boolean;
  readonly connected_since: number | null;
}

export interface ControlHolder {
  readonly user: string;
  readonly since: number;
}

export interface ControlStatus {
  readonly holder: ControlHolder | null;
}

export type EventKind = "connection" | "robot_state" | "flag" | "write" | "control";
export const EVENT_KINDS: readonly EventKind[] = [
  "connection",
  "robot_state",
  "flag",
  "write",
  "control",
];

/** An event as the WebSocket sends it: kind, time and the kind's own fields. */
export interface StreamEvent {
  readonly kind: EventKind | string;
  readonly time: number;
  readonly [key: string]: unknown;
}

export interface StampedFrame {
  readonly seq: number;
  /** received_at on the backend, seconds since the epoch */
  readonly t: number;
  readonly frame: Frame;
}

export type ServerMessage =
  | {
      readonly type: "hello";
      readonly layout_version: number;
      readonly connection: ConnectionStatus;
      readonly control: ControlStatus;
      readonly rate_hz: number | null;
    }
  | { readonly type: "frames"; readonly frames: readonly StampedFrame[] }
  | { readonly type: "dropped"; readonly count: number }
  | { readonly type: "status"; readonly connection: ConnectionStatus }
  | { readonly type: "event"; readonly event: StreamEvent }
  /** Some backends also push control changes as their own message; accepted, never required. */
  | { readonly type: "control"; readonly control: ControlStatus };

function isObject(v: unknown): v is Record<string, unknown> {
  return typeof v === "object" && v !== null && !Array.isArray(v);
}

/**
 * Parse one WebSocket text message; null for anything that is not a message of the contract
 * (the caller counts it and carries on with the last good state).
 */
export function parseServerMessage(text: string): ServerMessage | null {
  let data: unknown;
  try {
    data = JSON.parse(text);
  } catch {
    return null;
  }
  if (!isObject(data) || typeof data.type !== "string") return null;
  switch (data.type) {
    case "hello":
      if (!isObject(data.connection) || !isObject(data.control)) return null;
      return data as unknown as ServerMessage;
    case "frames": {
      if (!Array.isArray(data.frames)) return null;
      const ok = data.frames.every(
        (f: unknown) =>
          isObject(f) && typeof f.seq === "number" && typeof f.t === "number" && isObject(f.frame),
      );
      return ok ? (data as unknown as ServerMessage) : null;
    }
    case "dropped":
      return typeof data.count === "number" ? (data as unknown as ServerMessage) : null;
    case "status":
      return isObject(data.connection) ? (data as unknown as ServerMessage) : null;
    case "event":
      return isObject(data.event) && typeof data.event.kind === "string"
        ? (data as unknown as ServerMessage)
        : null;
    case "control":
      return isObject(data.control) ? (data as unknown as ServerMessage) : null;
    default:
      return null;
  }
}

export interface User {
  readonly name: string;
  readonly role: "viewer" | "operator" | "admin" | string;
}

const ROLE_RANK: Readonly<Record<string, number>> = { viewer: 0, operator: 1, admin: 2 };

export function roleAtLeast(user: User | null, role: "viewer" | "operator" | "admin"): boolean {
  if (user === null) return false;
  return (ROLE_RANK[user.role] ?? -1) >= (ROLE_RANK[role] ?? 99);
}

export interface CommandState {
  readonly image: CommandImage;
  readonly run: boolean;
}

export interface AuditItem {
  readonly id: number;
  readonly time: number;
  readonly user: string | null;
  readonly client: string | null;
  readonly action: string;
  readonly fields: unknown;
  readonly before: unknown;
  readonly requested: unknown;
  readonly outcome: string;
  readonly reason: string | null;
}

export interface EventItem {
  readonly id: number;
  readonly time: number;
  readonly kind: string;
  readonly data: unknown;
}

export interface Page<T> {
  readonly items: readonly T[];
  readonly total: number;
}
