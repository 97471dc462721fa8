/**
 * Layer: the write state of each writable control (plain TypeScript, no React, no fetch).
 *
 * A control is keyed by "<command field>.<index>" (e.g. "controlbox_do.2"). Its display follows
 * one rule: while a PATCH is outstanding it shows *pending*; once the backend confirms, the
 * confirmed value until the display shows the robot's frame that confirmed it or a newer one
 * (the answer names it: `seq`; the PATCH answer and the WebSocket frame race, and on a busy
 * machine the stream can lag the answer by more than a second), then always the robot's actual
 * value. A confirmation without a frame (bit input registers) holds for `confirmHold_ms`. A refusal or
 * timeout leaves the display on the actual value and keeps the reason next to the control until
 * the next write of that control.
 */
export type WriteValue = boolean | number;

export type WritePhase =
  | { readonly kind: "idle" }
  | { readonly kind: "pending"; readonly token: number; readonly requested: WriteValue; readonly since_ms: number }
  | {
      readonly kind: "confirmed";
      readonly requested: WriteValue;
      readonly at_ms: number;
      readonly latency_ms: number | null;
      /** The stream's number of the frame that showed it (null: no frame confirms it). */
      readonly seq: number | null;
      /** Still shown as written: the display has not reached its frame yet. */
      readonly held: boolean;
    }
  | { readonly kind: "refused"; readonly requested: WriteValue; readonly reason: string; readonly at_ms: number }
  | { readonly kind: "timeout"; readonly requested: WriteValue; readonly reason: string; readonly at_ms: number };

export interface WriteView {
  /** "pending" while outstanding, else what to show (null: nothing known yet). */
  readonly shown: WriteValue | "pending" | null;
  readonly pending: boolean;
  /** The refusal or timeout reason to show next to the control, if any. */
  readonly reason: string | null;
  readonly phase: WritePhase["kind"];
}

/** The answer of one PATCH, classified. */
export type WriteOutcome =
  | { readonly kind: "confirmed"; readonly latency_ms: number | null; readonly seq: number | null }
  | { readonly kind: "refused"; readonly reason: string }
  | { readonly kind: "timeout"; readonly reason: string };

export const CONFIRM_HOLD_MS = 1000;
/** Longest a confirmed value waits for its frame (a stream that stopped: the display says stale). */
export const FRAME_HOLD_MAX_MS = 10_000;

export function writeKey(field: string, index: number): string {
  return `${field}.${index}`;
}

/** Same value as far as a display is concerned (REAL values pass through float32). */
export function sameValue(a: WriteValue | null | undefined, b: WriteValue | null | undefined): boolean {
  if (a === null || a === undefined || b === null || b === undefined) return false;
  if (typeof a === "boolean" || typeof b === "boolean") return a === b;
  return Math.abs(a - b) <= 1e-4 * Math.max(1, Math.abs(a), Math.abs(b));
}

function reasonOf(body: unknown, fallback: string): string {
  if (typeof body === "object" && body !== null && "detail" in body) {
    const detail = (body as { detail: unknown }).detail;
    if (typeof detail === "string") return detail;
    if (typeof detail === "object" && detail !== null) {
      // The reason is shown next to the control it is about, so the field name is not repeated.
      const d = detail as { reason?: unknown; msg?: unknown };
      const reason = typeof d.reason === "string" ? d.reason : typeof d.msg === "string" ? d.msg : null;
      if (reason !== null) return reason;
    }
    if (Array.isArray(detail)) {
      // FastAPI's own request-validation shape: [{"loc": […], "msg": "…"}].
      const first = detail[0] as { msg?: unknown } | undefined;
      if (first !== undefined && typeof first.msg === "string") return first.msg;
    }
  }
  return fallback;
}

/** Classify a `PATCH /api/v1/robots/{name}/command` answer (docs/api.md, "Writing"). */
export function classifyWriteResponse(status: number, body: unknown): WriteOutcome {
  if (status === 200) {
    const latency =
      typeof body === "object" && body !== null && typeof (body as { latency_ms?: unknown }).latency_ms === "number"
        ? (body as { latency_ms: number }).latency_ms
        : null;
    const seq = typeof body === "object" && body !== null && typeof (body as { seq?: unknown }).seq === "number" ? (body as { seq: number }).seq : null;
    return { kind: "confirmed", latency_ms: latency, seq };
  }
  if (status === 504) return { kind: "timeout", reason: reasonOf(body, "no confirmation from the robot in time") };
  const fallback: Readonly<Record<number, string>> = {
    401: "not logged in",
    403: "your role may not write",
    404: "the service has no such robot",
    409: "refused: not connected, read-only mode, or control not held",
    413: "the request is too large",
    422: "invalid value",
    429: "too many requests: try again shortly",
  };
  return { kind: "refused", reason: reasonOf(body, fallback[status] ?? `refused (HTTP ${status})`) };
}

type Listener = () => void;

export class WriteTracker {
  private readonly phases = new Map<string, WritePhase>();
  private readonly listeners = new Set<Listener>();
  private nextToken = 1;
  private readonly now: () => number;
  private readonly confirmHold_ms: number;
  private version = 0;
  private shownSeq: number | null = null;

  constructor(now: () => number = Date.now, confirmHold_ms = CONFIRM_HOLD_MS) {
    this.now = now;
    this.confirmHold_ms = confirmHold_ms;
  }

  subscribe = (listener: Listener): (() => void) => {
    this.listeners.add(listener);
    return () => {
      this.listeners.delete(listener);
    };
  };

  /** Changes whenever any phase changes (for useSyncExternalStore). */
  getVersion = (): number => this.version;

  phase(key: string): WritePhase {
    return this.phases.get(key) ?? { kind: "idle" };
  }

  isPending(key: string): boolean {
    return this.phase(key).kind === "pending";
  }

  /** Start a write of `requested` to each key; returns the token to settle it with. */
  begin(keys: readonly string[], requested: readonly WriteValue[]): number {
    const token = this.nextToken++;
    const since_ms = this.now();
    keys.forEach((key, i) => {
      const value = requested[i];
      if (value === undefined) return;
      this.phases.set(key, { kind: "pending", token, requested: value, since_ms });
    });
    this.changed();
    return token;
  }

  /** Settle the write `token` on `keys`; a later write of the same key wins over an older one. */
  settle(keys: readonly string[], token: number, outcome: WriteOutcome): void {
    const at_ms = this.now();
    for (const key of keys) {
      const phase = this.phases.get(key);
      if (phase === undefined || phase.kind !== "pending" || phase.token !== token) continue;
      const requested = phase.requested;
      if (outcome.kind === "confirmed") {
        const held = outcome.seq === null || this.shownSeq === null || this.shownSeq < outcome.seq;
        this.phases.set(key, { kind: "confirmed", requested, at_ms, latency_ms: outcome.latency_ms, seq: outcome.seq, held });
      } else {
        this.phases.set(key, { kind: outcome.kind, requested, reason: outcome.reason, at_ms });
      }
    }
    this.changed();
  }

  /** The stream's number of the newest frame the display shows: confirmations it reached show the
   * robot's actual value from now on. */
  showing(seq: number | null): void {
    this.shownSeq = seq;
    if (seq === null) return;
    let released = false;
    for (const [key, phase] of this.phases) {
      if (phase.kind === "confirmed" && phase.held && phase.seq !== null && seq >= phase.seq) {
        this.phases.set(key, { ...phase, held: false });
        released = true;
      }
    }
    if (released) this.changed();
  }

  /** Forget a shown reason (the person dismissed it). */
  clear(key: string): void {
    if (this.phases.delete(key)) this.changed();
  }

  /** What a control shows, given the robot's actual value (null: unknown or stale). */
  view(key: string, actual: WriteValue | null | undefined): WriteView {
    const phase = this.phase(key);
    const known = actual === undefined ? null : actual;
    switch (phase.kind) {
      case "idle":
        return { shown: known, pending: false, reason: null, phase: "idle" };
      case "pending":
        return { shown: "pending", pending: true, reason: null, phase: "pending" };
      case "confirmed": {
        const hold_ms = phase.seq === null ? this.confirmHold_ms : FRAME_HOLD_MAX_MS;
        const holding = phase.held && !sameValue(known, phase.requested) && this.now() - phase.at_ms < hold_ms;
        return { shown: holding ? phase.requested : known, pending: false, reason: null, phase: "confirmed" };
      }
      case "refused":
      case "timeout":
        return { shown: known, pending: false, reason: phase.reason, phase: phase.kind };
    }
  }

  private changed(): void {
    this.version++;
    for (const listener of this.listeners) listener();
  }
}

/** The answer of a request: HTTP status and parsed JSON body (null if none). */
export interface HttpAnswer {
  readonly status: number;
  readonly body: unknown;
}

/**
 * Write `patch` (which sets `values[i]` on `keys[i]`) through `send`, tracking every key:
 * pending now, then confirmed, refused or timed out by the answer. A network failure is a
 * refusal with its reason; nothing is assumed to have changed on the robot.
 */
export async function performWrite(
  tracker: WriteTracker,
  keys: readonly string[],
  values: readonly WriteValue[],
  send: () => Promise<HttpAnswer>,
): Promise<WriteOutcome> {
  const token = tracker.begin(keys, values);
  let outcome: WriteOutcome;
  try {
    const answer = await send();
    outcome = classifyWriteResponse(answer.status, answer.body);
  } catch (error) {
    const message = error instanceof Error ? error.message : String(error);
    outcome = { kind: "refused", reason: `request failed: ${message}` };
  }
  tracker.settle(keys, token, outcome);
  return outcome;
}
