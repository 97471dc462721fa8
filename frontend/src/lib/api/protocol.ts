/**
 * Layer: names for the service's REST and WebSocket shapes, and a tolerant parser for WebSocket
 * messages. No React, no DOM, no network.
 *
 * Every shape is the service's own, from its OpenAPI document: `src/generated/api.ts` is
 * generated from it (`make codegen`), and this module only gives the schemas short names. A
 * frame's fields are the layout's (`src/generated/layout.ts`); a test checks that the OpenAPI
 * frame and the layout's frame agree.
 */
import type { components } from "../../generated/api";
import type { Frame } from "../../generated/layout";

type Schemas = components["schemas"];

export type ConnectionStatus = Schemas["ConnectionStatus"];
export type LinkState = ConnectionStatus["state"];
export type ControlHolder = Schemas["Holder"];
export type ControlStatus = Schemas["ControlStatus"];
export type RobotSummary = Schemas["RobotSummary"];
export type AlarmSummary = Schemas["AlarmSummary"];
export type CellAlarmSummary = Schemas["CellAlarmSummary"];
/** The kiosk's settings (plot window, shifts), from the stream's hello. */
export type KioskConfig = Schemas["KioskConfig"];
export type RobotStatus = Schemas["RobotStatus"];
export type CommandState = Schemas["CommandState"];
export type ApiErrorBody = Schemas["ApiErrorBody"];
export type AuditItem = Schemas["AuditRow"];
export type EventPage = Schemas["EventPage"];
export type AuditPage = Schemas["AuditPage"];
/** An event as the log and the WebSocket carry it: kind, time, robot and the kind's own fields. */
export type StreamEvent = Schemas["EventMessage"]["event"];
export type EventItem = EventPage["items"][number];
export type EventKind = StreamEvent["kind"];
/** A frame with its sequence number and receive time; its fields typed by the layout. */
export type StampedFrame = Omit<Schemas["FrameItem"], "frame"> & { readonly frame: Frame };
export type FramesMessage = Omit<Schemas["FramesMessage"], "frames"> & { readonly frames: readonly StampedFrame[] };
export type ServerMessage = Exclude<Schemas["StreamMessage"], { type: "frames" }> | FramesMessage;

/**
 * Every event kind of the contract, in the order the filter offers them (an object's string
 * keys keep their order). Written as an object that must have exactly the generated
 * `EventKind`s as keys, so a kind added to the service's OpenAPI document (`make codegen`) fails
 * to compile here until it is listed, and a kind the contract dropped fails too.
 */
const EVENT_KIND_SET = {
  connection: true,
  robot_state: true,
  flag: true,
  write: true,
  control: true,
  alarm: true,
  recording: true,
  session: true,
  cycle: true,
  health: true,
} as const satisfies Record<EventKind, true>;

export const EVENT_KINDS = Object.keys(EVENT_KIND_SET) as (keyof typeof EVENT_KIND_SET)[];

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
    case "subscribed":
      return (data.fields === null || Array.isArray(data.fields)) && (data.rate_hz === null || typeof data.rate_hz === "number")
        ? (data as unknown as ServerMessage)
        : null;
    default:
      return null;
  }
}

export type User = Schemas["User"];
export type Role = User["role"];

const ROLES: readonly string[] = ["viewer", "operator", "admin"] satisfies readonly Role[];

/** A user as an auth answer carries it, or null when it is not one (an answer read untyped). */
export function userOf(value: unknown): User | null {
  if (!isObject(value) || typeof value.name !== "string" || typeof value.role !== "string") return null;
  return ROLES.includes(value.role) ? { name: value.name, role: value.role as Role } : null;
}

const ROLE_RANK: Readonly<Record<string, number>> = { viewer: 0, operator: 1, admin: 2 };

export function roleAtLeast(user: User | null, role: "viewer" | "operator" | "admin"): boolean {
  if (user === null) return false;
  return (ROLE_RANK[user.role] ?? -1) >= (ROLE_RANK[role] ?? 99);
}
