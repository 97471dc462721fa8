/**
 * Layer: pure (no DOM, no Plotly). A value axis as Plotly draws an autoranged one, for the
 * static picture of a live plot (plots/canvasPlot.ts): the range of the data padded by 5 % of the
 * axis at each end (Plotly's `padded` lines), and ticks at round steps (1, 2, 5 × 10ⁿ) about one
 * per 40 px of the axis, labelled with as many decimals as the step needs and a real minus sign.
 * So the picture and Plotly's interactive plot, which replaces it under the pointer, agree.
 */

export interface ValueTicks {
  readonly values: number[];
  readonly labels: string[];
}

/** The autoranged axis over [min, max]: padded 5 % of the axis length each end; a constant ±1. */
export function paddedRange(min: number, max: number): [number, number] {
  if (!Number.isFinite(min) || !Number.isFinite(max)) return [-1, 1];
  if (max === min) return [min - 1, max + 1];
  // The data fills the middle 90 % of the axis.
  const pad = ((max - min) * 0.05) / 0.9;
  return [min - pad, max + pad];
}

/** The round step (1, 2 or 5 × 10ⁿ) of about `count` ticks over `span`. */
export function valueStep(span: number, count: number): number {
  const rough = Math.abs(span) / Math.max(1, count);
  if (!(rough > 0) || !Number.isFinite(rough)) return 1;
  const base = 10 ** Math.floor(Math.log10(rough));
  const ratio = rough / base;
  return base * (ratio <= 1 ? 1 : ratio <= 2 ? 2 : ratio <= 5 ? 5 : 10);
}

/** Ticks over an axis `length_px` long: Plotly's count, about one per 40 px, 4 to 9 steps. */
export function valueTicks(from: number, to: number, length_px: number): ValueTicks {
  const values: number[] = [];
  const labels: string[] = [];
  if (!Number.isFinite(from) || !Number.isFinite(to) || !(to > from)) return { values, labels };
  const steps = Math.min(9, Math.max(4, (Number.isFinite(length_px) ? length_px : 200) / 40)) + 1;
  const step = valueStep(to - from, steps);
  const decimals = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
  for (let k = Math.ceil(from / step); k * step <= to; k++) {
    // (+ 0: never a −0 tick.)
    const v = k * step + 0;
    values.push(v);
    labels.push(valueLabel(v, decimals));
  }
  return { values, labels };
}

/** A tick's label: `decimals` decimals, a real minus sign, never "−0". */
export function valueLabel(v: number, decimals: number): string {
  const text = Math.abs(v) < 10 ** -(decimals + 1) ? (0).toFixed(decimals) : v.toFixed(decimals);
  return text.startsWith("-") ? `\u2212${text.slice(1)}` : text;
}
