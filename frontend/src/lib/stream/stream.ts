/**
 * Layer: the WebSocket client of `WS /api/v1/robots/{name}/stream` (plain TypeScript, no React).
 *
 * Connects, parses messages (bad ones are counted and skipped), and reconnects by itself with
 * exponential backoff and jitter after any close. A watchdog closes a socket that has been
 * silent for too long (the backend sends a status about once a second), so a half-open TCP
 * connection of a kiosk left running for days does not freeze the display silently.
 * A page may ask for part of the stream (`subscribe`: the fields it shows, at the rate it draws;
 * docs/api.md): sent at once when the socket is open, and again on every new socket.
 * Must not import React or any component.
 */
import { Backoff, DEFAULT_BACKOFF, type BackoffOptions } from "./backoff";
import type { SocketState } from "./health";
import { parseServerMessage, type ServerMessage } from "../api/protocol";

/** The part of the browser's WebSocket this client uses (a test passes its own). */
export interface SocketLike {
  onopen: ((ev: unknown) => void) | null;
  onmessage: ((ev: { data: unknown }) => void) | null;
  onclose: ((ev: { code?: number; reason?: string }) => void) | null;
  onerror: ((ev: unknown) => void) | null;
  close(code?: number, reason?: string): void;
  send?(data: string): void;
}

/** What a page asks of the stream (the `subscribe` message): null fields or rate, all of it. */
export interface Subscription {
  readonly fields: readonly string[] | null;
  readonly rate_hz: number | null;
}

/** The `subscribe` message of a subscription (null: every field of every frame again). */
export function subscribeMessage(subscription: Subscription | null): string {
  return JSON.stringify({ type: "subscribe", fields: subscription?.fields ?? null, rate_hz: subscription?.rate_hz ?? null });
}

/** Whether two subscriptions ask the same (null: none). */
export function sameSubscription(a: Subscription | null, b: Subscription | null): boolean {
  if (a === null || b === null) return a === b;
  return a.rate_hz === b.rate_hz && (a.fields === null || b.fields === null ? a.fields === b.fields : a.fields.join() === b.fields.join());
}

export type SocketFactory = (url: string) => SocketLike;

export interface StreamCallbacks {
  onMessage(message: ServerMessage): void;
  onSocketState(state: SocketState): void;
  /** Why the service closed the socket, in words (close codes of docs/api.md), or null. */
  onCloseReason?(reason: string | null): void;
  onBadMessage?(): void;
}

/** The service's own close codes (docs/api.md, WebSocket). */
export const CLOSE_BAD_RATE = 4400;
export const CLOSE_LOGIN_REQUIRED = 4401;
export const CLOSE_UNKNOWN_ROBOT = 4404;
/** Policy violation (RFC 6455): the stream's session ended (logout, revoked, its user changed). */
export const CLOSE_SESSION_ENDED = 1008;

/** A person's words for why the service closed the stream (null: an ordinary close). */
export function closeReason(code: number | undefined, reason: string | undefined): string | null {
  const detail = reason !== undefined && reason !== "" ? `: ${reason}` : "";
  if (code === CLOSE_LOGIN_REQUIRED) return `the service requires a login to view${detail}`;
  if (code === CLOSE_BAD_RATE) return `the service refused the stream rate${detail}`;
  if (code === CLOSE_UNKNOWN_ROBOT) return `the service has no such robot${detail}`;
  if (code === CLOSE_SESSION_ENDED) return `the service closed the stream${detail !== "" ? detail : ": its session ended"}`;
  if (code !== undefined && code >= 4000) return `the service closed the stream (${code})${detail}`;
  return null;
}

export interface StreamOptions {
  readonly backoff?: BackoffOptions;
  readonly random?: () => number;
  /** Close and reconnect when no message came for this long. */
  readonly silenceTimeout_ms?: number;
  readonly socketFactory?: SocketFactory;
}

export const DEFAULT_SILENCE_TIMEOUT_MS = 5000;

/**
 * ws(s)://host/api/v1/robots/NAME/stream[?rate=HZ&token=…] for the page's own origin; without a
 * robot, the service's default robot (its first) on `/api/v1/stream`.
 */
export function streamUrl(
  location: { protocol: string; host: string },
  robot: string | null,
  rate_hz?: number,
  token?: string | null,
): string {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const query = new URLSearchParams();
  if (rate_hz !== undefined) query.set("rate", String(rate_hz));
  if (token !== undefined && token !== null && token !== "") query.set("token", token);
  const q = query.toString();
  const path = robot === null ? "/api/v1/stream" : `/api/v1/robots/${encodeURIComponent(robot)}/stream`;
  return `${scheme}://${location.host}${path}${q === "" ? "" : `?${q}`}`;
}

export class StreamClient {
  private readonly url: () => string;
  private readonly callbacks: StreamCallbacks;
  private readonly backoff: Backoff;
  private readonly silenceTimeout_ms: number;
  private readonly factory: SocketFactory;
  private socket: SocketLike | null = null;
  private retryTimer: ReturnType<typeof setTimeout> | null = null;
  private silenceTimer: ReturnType<typeof setTimeout> | null = null;
  private running = false;
  private subscription: Subscription | null = null;
  /** A socket has been asked for part of the stream: a return to all of it must be said. */
  private subscribed = false;
  /** This page is ending its own session: the service's 1008 close that follows is expected. */
  private sessionEndExpected = false;
  /** Number of connection attempts after the first. */
  reconnects = 0;
  badMessages = 0;
  /** The delay chosen for the pending retry, for display and tests. */
  lastDelay_ms: number | null = null;

  constructor(url: () => string, callbacks: StreamCallbacks, options: StreamOptions = {}) {
    this.url = url;
    this.callbacks = callbacks;
    this.backoff = new Backoff(options.backoff ?? DEFAULT_BACKOFF, options.random);
    this.silenceTimeout_ms = options.silenceTimeout_ms ?? DEFAULT_SILENCE_TIMEOUT_MS;
    this.factory =
      options.socketFactory ?? ((u: string) => new WebSocket(u) as unknown as SocketLike);
  }

  start(): void {
    if (this.running) return;
    this.running = true;
    this.connect();
  }

  stop(): void {
    this.running = false;
    this.clearTimers();
    this.dropSocket();
    this.callbacks.onSocketState("closed");
  }

  /**
   * This page is about to end its own session (its user logs out): the service will close this
   * socket with 1008. That close is then no news to show ("session ended") and no reason to back
   * off: the client restarts at once instead (which also forgets the expectation).
   */
  expectSessionEnd(): void {
    this.sessionEndExpected = true;
  }

  /**
   * Ask for the fields a page shows at the rate it draws (null: every field of every frame): on
   * the open socket now, and on each new one when it opens.
   */
  subscribe(subscription: Subscription | null): void {
    if (sameSubscription(subscription, this.subscription)) return;
    this.subscription = subscription;
    this.sendSubscription();
  }

  private sendSubscription(): void {
    const socket = this.socket;
    if (socket === null || socket.send === undefined || !this.open) return;
    if (this.subscription === null && !this.subscribed) return;
    try {
      socket.send(subscribeMessage(this.subscription));
      this.subscribed = this.subscription !== null;
    } catch {
      // closing: the next socket sends it
    }
  }

  private open = false;

  /** Reconnect now (e.g. after a login, so the new socket carries the session). */
  restart(): void {
    if (!this.running) return;
    this.sessionEndExpected = false;
    this.clearTimers();
    this.dropSocket();
    this.backoff.reset();
    this.connect();
  }

  private connect(): void {
    this.callbacks.onSocketState("connecting");
    let socket: SocketLike;
    try {
      socket = this.factory(this.url());
    } catch {
      this.scheduleRetry();
      return;
    }
    this.socket = socket;
    this.open = false;
    this.subscribed = false;
    socket.onopen = () => {
      if (this.socket !== socket) return;
      this.open = true;
      this.sendSubscription();
      this.callbacks.onCloseReason?.(null);
      this.callbacks.onSocketState("open");
      this.armSilence();
    };
    socket.onmessage = (ev) => {
      if (this.socket !== socket) return;
      this.armSilence();
      const message = typeof ev.data === "string" ? parseServerMessage(ev.data) : null;
      if (message === null) {
        this.badMessages++;
        this.callbacks.onBadMessage?.();
        return;
      }
      // Only a hello proves the service answers: a socket that opens and closes at once
      // (a proxy without a backend) keeps backing off.
      if (message.type === "hello") this.backoff.reset();
      this.callbacks.onMessage(message);
    };
    socket.onerror = () => {
      // onclose follows; nothing to do here.
    };
    socket.onclose = (ev) => {
      if (this.socket !== socket) return;
      this.socket = null;
      this.clearSilence();
      if (this.sessionEndExpected && ev.code === CLOSE_SESSION_ENDED) {
        this.callbacks.onCloseReason?.(null);
        this.restart();
        return;
      }
      this.callbacks.onCloseReason?.(closeReason(ev.code, ev.reason));
      this.callbacks.onSocketState("closed");
      this.scheduleRetry();
    };
  }

  private scheduleRetry(): void {
    if (!this.running || this.retryTimer !== null) return;
    const delay = this.backoff.next_ms();
    this.lastDelay_ms = delay;
    this.retryTimer = setTimeout(() => {
      this.retryTimer = null;
      if (!this.running) return;
      this.reconnects++;
      this.connect();
    }, delay);
  }

  private armSilence(): void {
    this.clearSilence();
    this.silenceTimer = setTimeout(() => {
      this.silenceTimer = null;
      const socket = this.socket;
      if (socket === null) return;
      // Treat a silent socket as closed: forget it first so its late onclose is ignored.
      this.socket = null;
      try {
        socket.close(4000, "silent");
      } catch {
        // already closed
      }
      this.callbacks.onSocketState("closed");
      this.scheduleRetry();
    }, this.silenceTimeout_ms);
  }

  private clearSilence(): void {
    if (this.silenceTimer !== null) clearTimeout(this.silenceTimer);
    this.silenceTimer = null;
  }

  private clearTimers(): void {
    this.clearSilence();
    if (this.retryTimer !== null) clearTimeout(this.retryTimer);
    this.retryTimer = null;
  }

  private dropSocket(): void {
    const socket = this.socket;
    this.socket = null;
    if (socket !== null) {
      try {
        socket.close(1000, "client");
      } catch {
        // already closed
      }
    }
  }
}
