/**
 * Layer: a login session's idle clock as the page keeps it (pure: no React, no DOM; the
 * requests and the timers are given).
 *
 * The service renews a session only on its person's actions (docs/api.md "Login"): a changing
 * request, or `POST /api/v1/auth/activity`, which this sends when the person clicks or types
 * (at most once per `reportEvery_ms`, the last action of a burst reported at its end, so the
 * deadline is never more than that behind the person). The page's own polling and its stream
 * never renew it: the service reads the method, not anything this page claims.
 *
 * It also keeps the session's deadline: when the time is up it asks the service (a read: it
 * renews nothing) and, the session gone, says so at once (`onExpired`): the page turns to
 * logged out, "Session expired: log in again". A session renewed meanwhile elsewhere (another
 * window of the same login, a write) answers with its new deadline, which is waited for instead.
 */

/** What the service says of the session (`Me`): its user and the time it has left. */
export interface SessionState {
  readonly user: unknown;
  readonly idle_timeout_s?: number | null;
  readonly idle_expires_in_s?: number | null;
}

export interface SessionIdleDeps {
  /** `POST /api/v1/auth/activity`: the session after it, `null` when there is none (401). */
  readonly report: () => Promise<SessionState | null>;
  /** `GET /api/v1/auth/me`: the session as it is (renews nothing). */
  readonly check: () => Promise<SessionState | null>;
  readonly onExpired: () => void;
  readonly now_ms?: () => number;
  readonly setTimer?: (fn: () => void, ms: number) => unknown;
  readonly clearTimer?: (timer: unknown) => void;
}

/** The longest wait between two reports of a busy person, ms (a quarter of the lifetime if shorter). */
export const REPORT_EVERY_MAX_MS = 30_000;
/** Asked this long after the deadline: the service's sweep ends the session within a second. */
export const EXPIRY_SLACK_MS = 250;

/** After a request that failed, asked again this much later, ms. */
export const RETRY_MS = 2000;

/** How often a person's actions are reported for a session that idles out after `idleTimeout_s`. */
export function reportEvery_ms(idleTimeout_s: number): number {
  return Math.max(500, Math.min(REPORT_EVERY_MAX_MS, (idleTimeout_s * 1000) / 4));
}

/** The message the page shows when its session idled out. */
export const SESSION_EXPIRED_WORDS = "Session expired: log in again";

export class SessionIdleWatch {
  private readonly deps: SessionIdleDeps;
  private readonly now: () => number;
  private readonly setTimer: (fn: () => void, ms: number) => unknown;
  private readonly clearTimer: (timer: unknown) => void;
  private deadlineTimer: unknown = null;
  private trailingTimer: unknown = null;
  private lastReport_ms = -Infinity;
  private every_ms = REPORT_EVERY_MAX_MS;
  private stopped = false;
  private ended = false;

  constructor(deps: SessionIdleDeps) {
    this.deps = deps;
    this.now = deps.now_ms ?? (() => Date.now());
    this.setTimer = deps.setTimer ?? ((fn, ms) => setTimeout(fn, ms));
    this.clearTimer = deps.clearTimer ?? ((t) => clearTimeout(t as ReturnType<typeof setTimeout>));
  }

  /** Begin with what the service says now (asked once). */
  start(): void {
    void this.ask(this.deps.check);
  }

  stop(): void {
    this.stopped = true;
    this.clear();
  }

  /** The person clicked, typed or scrolled: reported now, or at the end of the current window. */
  personActed(): void {
    if (this.stopped || this.ended) return;
    const since_ms = this.now() - this.lastReport_ms;
    if (since_ms >= this.every_ms) {
      this.report();
      return;
    }
    if (this.trailingTimer !== null) return;
    this.trailingTimer = this.setTimer(() => {
      this.trailingTimer = null;
      this.report();
    }, this.every_ms - since_ms);
  }

  private report(): void {
    this.lastReport_ms = this.now();
    void this.ask(this.deps.report);
  }

  private async ask(request: () => Promise<SessionState | null>): Promise<void> {
    let state: SessionState | null;
    try {
      state = await request();
    } catch {
      // The service unreachable: asked again in a while (its sweep ends the session anyway).
      if (!this.stopped && !this.ended && this.deadlineTimer === null) {
        this.deadlineTimer = this.setTimer(() => {
          this.deadlineTimer = null;
          void this.ask(this.deps.check);
        }, RETRY_MS);
      }
      return;
    }
    if (this.stopped || this.ended) return;
    this.take(state);
  }

  /** The session as the service said it: expired, or its next deadline. */
  private take(state: SessionState | null): void {
    if (state === null || state.user === null || state.user === undefined) {
      this.ended = true;
      this.clear();
      this.deps.onExpired();
      return;
    }
    const left_s = state.idle_expires_in_s;
    if (typeof state.idle_timeout_s === "number") this.every_ms = reportEvery_ms(state.idle_timeout_s);
    if (this.deadlineTimer !== null) this.clearTimer(this.deadlineTimer);
    this.deadlineTimer = null;
    if (typeof left_s !== "number") return; // an API token's: it never idles out
    this.deadlineTimer = this.setTimer(() => {
      this.deadlineTimer = null;
      void this.ask(this.deps.check);
    }, left_s * 1000 + EXPIRY_SLACK_MS);
  }

  private clear(): void {
    if (this.deadlineTimer !== null) this.clearTimer(this.deadlineTimer);
    if (this.trailingTimer !== null) this.clearTimer(this.trailingTimer);
    this.deadlineTimer = this.trailingTimer = null;
  }
}
