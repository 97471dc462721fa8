/**
 * Layer: pure reconnect timing (no React, no DOM, no network).
 *
 * Exponential backoff with jitter: the n-th retry waits a random time in
 * [(1 − jitter)·d, d] with d = min(max, initial·factorⁿ). The randomness spreads many kiosks
 * that lost the same backend apart, so they do not all reconnect in the same millisecond.
 */
export interface BackoffOptions {
  readonly initial_ms: number;
  readonly max_ms: number;
  readonly factor: number;
  /** Fraction of the delay that is random, 0 (none) … 1 (full jitter). */
  readonly jitter: number;
}

export const DEFAULT_BACKOFF: BackoffOptions = {
  initial_ms: 250,
  max_ms: 10_000,
  factor: 2,
  jitter: 0.5,
};

export class Backoff {
  readonly options: BackoffOptions;
  private attempts = 0;
  private readonly random: () => number;

  constructor(options: BackoffOptions = DEFAULT_BACKOFF, random: () => number = Math.random) {
    if (!(options.initial_ms > 0) || !(options.max_ms >= options.initial_ms)) {
      throw new Error("backoff needs 0 < initial_ms ≤ max_ms");
    }
    if (!(options.factor >= 1)) throw new Error("backoff factor must be ≥ 1");
    if (!(options.jitter >= 0 && options.jitter <= 1)) throw new Error("jitter must be in [0, 1]");
    this.options = options;
    this.random = random;
  }

  /** Retries so far since the last reset. */
  get attempt(): number {
    return this.attempts;
  }

  /** Upper bound of the delay of the next retry (no randomness). */
  ceiling_ms(): number {
    const { initial_ms, max_ms, factor } = this.options;
    // Capped exponent: factor^attempts overflows to Infinity after ~1000 attempts anyway.
    return Math.min(max_ms, initial_ms * Math.pow(factor, Math.min(this.attempts, 64)));
  }

  /** The delay before the next retry; counts the retry. */
  next_ms(): number {
    const ceiling = this.ceiling_ms();
    this.attempts++;
    const r = Math.min(Math.max(this.random(), 0), 1);
    return ceiling * (1 - this.options.jitter * r);
  }

  /** After a successful connection: the next failure starts from the initial delay again. */
  reset(): void {
    this.attempts = 0;
  }
}
