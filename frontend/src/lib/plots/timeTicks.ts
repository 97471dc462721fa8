/**
 * Layer: pure (no DOM, no Plotly). The time axis ticks of a live plot drawn on a linear axis.
 *
 * A live plot that nobody points at draws its time axis as a plain number axis with these ticks
 * (values and their "HH:MM:SS" labels) rather than as Plotly's date axis: a date axis reads
 * every sample's time through Plotly's date parser and works out date ticks on every redraw,
 * about a fifth of a redraw's time (bench/ui); this costs a few divisions. The times are the
 * plots' numeric dates: milliseconds shifted to the browser's local time, read as UTC.
 */

/** Tick steps (ms), the round ones a time axis uses. */
const STEPS_MS = [
  100, 200, 500, 1_000, 2_000, 5_000, 10_000, 15_000, 30_000, 60_000, 120_000, 300_000, 600_000, 900_000, 1_800_000,
  3_600_000, 7_200_000, 10_800_000, 21_600_000, 43_200_000, 86_400_000,
];

/** About one tick label per this many pixels of the plotting area. */
export const TICK_SPACING_PX = 110;

export interface TimeTicks {
  readonly tickvals: number[];
  readonly ticktext: string[];
}

/** The round step that gives about `count` ticks over `span_ms` (a few more rather than half). */
export function tickStep(span_ms: number, count: number): number {
  const wanted = (0.75 * span_ms) / Math.max(1, count);
  for (const step of STEPS_MS) if (step >= wanted) return step;
  return STEPS_MS[STEPS_MS.length - 1]!;
}

function two(n: number): string {
  return n < 10 ? `0${n}` : String(n);
}

/** A tick's label: the time of day, with tenths when the step is under a second. */
export function tickLabel(x: number, step_ms: number): string {
  const d = new Date(x);
  const hm = `${two(d.getUTCHours())}:${two(d.getUTCMinutes())}`;
  if (step_ms >= 60_000) return hm;
  const s = `${hm}:${two(d.getUTCSeconds())}`;
  return step_ms >= 1_000 ? s : `${s}.${Math.floor(d.getUTCMilliseconds() / 100)}`;
}

/**
 * Ticks at round times from `from` to `to` (numeric dates), about one per `spacing_px` of
 * `width_px`; Plotly draws those inside the axis' range.
 */
export function timeTicks(from: number, to: number, width_px: number, spacing_px = TICK_SPACING_PX): TimeTicks {
  const tickvals: number[] = [];
  const ticktext: string[] = [];
  if (!Number.isFinite(from) || !Number.isFinite(to) || !(to > from)) return { tickvals, ticktext };
  const width = Number.isFinite(width_px) && width_px > 0 ? width_px : 500;
  const count = Math.max(2, Math.round(width / spacing_px));
  const step = tickStep(to - from, count);
  // No tick so near the newest end that half its label would be cut off by the plot's edge.
  const last = to - ((to - from) / width) * 0.3 * spacing_px;
  for (let x = Math.ceil(from / step) * step; x <= last; x += step) {
    tickvals.push(x);
    ticktext.push(tickLabel(x, step));
  }
  return { tickvals, ticktext };
}
