/**
 * Layer: pure connection-health rules (no React, no DOM, no network).
 *
 * Three words for a person: connected (live data), stale (connected but the newest frame is too
 * old, or the backend says so), disconnected (no WebSocket, or the backend has no robot link).
 * Stale data is never shown as live.
 */
import type { ConnectionStatus } from "../api/protocol";

export type Health = "connected" | "stale" | "disconnected";
export type SocketState = "connecting" | "open" | "closed";

/** A frame older than this (as the browser sees it) makes the display stale. */
export const STALE_AFTER_MS = 1000;

export interface HealthInput {
  readonly socket: SocketState;
  readonly connection: ConnectionStatus | null;
  /** ms since the browser received the newest frame, null if none yet */
  readonly frameAge_ms: number | null;
  readonly staleAfter_ms?: number;
}

export function connectionHealth(input: HealthInput): Health {
  if (input.socket !== "open") return "disconnected";
  if (input.connection === null || input.connection.state !== "connected") return "disconnected";
  if (input.frameAge_ms === null) return "stale";
  if (input.connection.stale) return "stale";
  if (input.frameAge_ms > (input.staleAfter_ms ?? STALE_AFTER_MS)) return "stale";
  return "connected";
}

/** Packet loss as the connection badge shows it. */
export interface PacketLoss {
  /** The badge turns amber (data-packet-loss="high"). */
  readonly high: boolean;
  /** Its tooltip's words, null when not high. */
  readonly words: string | null;
}

/**
 * The service's packet-loss alarm (T→O gaps per minute above its threshold) turns a live badge
 * amber; a stale or disconnected badge keeps its own colour, which says more.
 */
export function packetLossOf(health: Health, connection: ConnectionStatus | null): PacketLoss {
  if (health !== "connected" || connection === null || connection.packet_loss_high !== true) return { high: false, words: null };
  const gaps = connection.gaps_per_min;
  return { high: true, words: `packet loss: ${gaps === null || gaps === undefined ? "?" : gaps} gaps in the last minute` };
}

/** "12 ms", "3.4 s", "5 min" — for ages and intervals. */
export function formatDuration_ms(ms: number | null | undefined): string {
  if (ms === null || ms === undefined || !Number.isFinite(ms)) return "—";
  if (ms < 1000) return `${Math.round(ms)} ms`;
  if (ms < 60_000) return `${(ms / 1000).toFixed(1)} s`;
  if (ms < 3_600_000) return `${Math.floor(ms / 60_000)} min`;
  return `${(ms / 3_600_000).toFixed(1)} h`;
}
