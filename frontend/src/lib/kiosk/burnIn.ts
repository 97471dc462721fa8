/**
 * Layer: pure burn-in protection for the kiosk (no React, no DOM).
 *
 * The whole kiosk view moves by a few pixels every `period_ms`, along a fixed cycle of offsets
 * that all stay within ±`amplitude_px`. The kiosk's padding is larger than the amplitude, so the
 * state badge and an emergency-stop banner are never pushed off screen or covered.
 */
export interface Offset {
  readonly dx_px: number;
  readonly dy_px: number;
}

/** Unit offsets visited in turn: a small loop around the centre, every point distinct. */
const CYCLE: readonly (readonly [number, number])[] = [
  [0, 0],
  [1, 0],
  [1, 1],
  [0, 1],
  [-1, 1],
  [-1, 0],
  [-1, -1],
  [0, -1],
  [1, -1],
];

export const BURN_IN_PERIOD_MS = 60_000;
export const BURN_IN_AMPLITUDE_PX = 6;

export function burnInOffset(
  now_ms: number,
  period_ms: number = BURN_IN_PERIOD_MS,
  amplitude_px: number = BURN_IN_AMPLITUDE_PX,
): Offset {
  const step = Math.floor(now_ms / period_ms);
  const index = ((step % CYCLE.length) + CYCLE.length) % CYCLE.length;
  const [ux, uy] = CYCLE[index] as readonly [number, number];
  return { dx_px: ux * amplitude_px, dy_px: uy * amplitude_px };
}
