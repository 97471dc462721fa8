/**
 * Layer: polling one answer of the service (plain TypeScript, no React, no DOM), as the fleet's
 * robot list, the health page's report and its baselines are: one request at a time (a slow
 * answer delays the next poll rather than piling requests up), the last good answer kept and
 * marked stale while the service does not answer. Subscribe and getSnapshot are React's
 * useSyncExternalStore pair.
 */

/** What one fetch gave: the value, or why there is none. */
export type Fetched<T> = { readonly ok: true; readonly value: T } | { readonly ok: false; readonly status: number; readonly reason: string };

export interface PolledSnapshot<T> {
  /** The last good answer (null before one came). */
  readonly value: T | null;
  /** Why the last poll failed (null: it did not). */
  readonly error: string | null;
  /** The status of the last failed poll (0: no answer at all; null: it did not fail). */
  readonly status: number | null;
  /** `value` is older than the newest poll (that one failed). */
  readonly stale: boolean;
  /** A first answer (good or bad) has come. */
  readonly loaded: boolean;
}

type Listener = () => void;

export class Poller<T> {
  private readonly listeners = new Set<Listener>();
  private timer: ReturnType<typeof setTimeout> | null = null;
  private running = false;
  private generation = 0;
  private current: PolledSnapshot<T> = { value: null, error: null, status: null, stale: false, loaded: false };

  constructor(
    private readonly fetchValue: () => Promise<Fetched<T>>,
    private readonly interval_ms: number,
  ) {}

  subscribe = (listener: Listener): (() => void) => {
    this.listeners.add(listener);
    return () => {
      this.listeners.delete(listener);
    };
  };

  getSnapshot = (): PolledSnapshot<T> => this.current;

  start(): void {
    if (this.running) return;
    this.running = true;
    void this.poll(++this.generation);
  }

  stop(): void {
    this.running = false;
    this.generation++;
    if (this.timer !== null) clearTimeout(this.timer);
    this.timer = null;
  }

  /** Poll now (after a re-baselining, a login) instead of waiting for the next turn. */
  refresh(): void {
    if (!this.running) return;
    if (this.timer !== null) clearTimeout(this.timer);
    this.timer = null;
    void this.poll(++this.generation);
  }

  private async poll(generation: number): Promise<void> {
    let answer: Fetched<T>;
    try {
      answer = await this.fetchValue();
    } catch (error) {
      answer = { ok: false, status: 0, reason: error instanceof Error ? error.message : String(error) };
    }
    // A stop or a refresh while this poll was out makes its answer (and its next turn) moot.
    if (!this.running || generation !== this.generation) return;
    this.current = answer.ok
      ? { value: answer.value, error: null, status: null, stale: false, loaded: true }
      : { ...this.current, error: answer.reason, status: answer.status, stale: this.current.value !== null, loaded: true };
    for (const listener of this.listeners) listener();
    this.timer = setTimeout(() => {
      this.timer = null;
      void this.poll(generation);
    }, this.interval_ms);
  }
}
