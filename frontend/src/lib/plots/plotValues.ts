/**
 * Layer: pure (no DOM, no Plotly, no React). A plot's values at one time, for the panel's cursor
 * (docs/architecture.md "Plots: one time axis for the panel"): from the ring's sample nearest
 * that time, or where the ring holds nothing there from the recording's answer the plot drew
 * (a bucket's minimum and maximum, or a raw frame's value). Samples are read where they are,
 * never copied into React state.
 */
import type { HistoryAnswer } from "./historyView";
import type { TraceInfo } from "./plots";
import type { SampleRing } from "../stream/ringBuffer";

/** One trace's value at the cursor: a sample's, or a bucket's minimum and maximum. */
export type TraceValue = { readonly value: number } | { readonly min: number; readonly max: number };

/** The ring's samples nearer to the cursor than this count (the stream's frames come every 10–20 ms). */
export const RING_TOLERANCE_MS = 250;

/**
 * The values of the ring's sample nearest `time_ms` (per channel of `channels`), or null when the
 * ring holds no sample within `tolerance_ms` of it.
 */
export function ringValuesAt(
  ring: SampleRing,
  channels: readonly number[],
  time_ms: number,
  tolerance_ms = RING_TOLERANCE_MS,
): (TraceValue | null)[] | null {
  if (ring.newestTime() === null || !Number.isFinite(time_ms)) return null;
  const after = ring.firstSeqAtOrAfter(time_ms);
  let best = -1;
  let bestDistance = Infinity;
  for (const seq of [after - 1, after]) {
    if (seq < ring.oldestSeq || seq >= ring.endSeq) continue;
    const distance = Math.abs(ring.timeAt(seq) - time_ms);
    if (distance < bestDistance) {
      best = seq;
      bestDistance = distance;
    }
  }
  if (best < 0 || bestDistance > tolerance_ms) return null;
  return channels.map((c) => {
    const v = ring.valueAt(c, best);
    return Number.isFinite(v) ? { value: v } : null;
  });
}

function finite(v: number | boolean | null | undefined): number | null {
  if (typeof v === "boolean") return v ? 1 : 0;
  return typeof v === "number" && Number.isFinite(v) ? v : null;
}

/**
 * The values of the recording's `answer` at `time_ms` for `traces`: the bucket (or raw frame)
 * nearest it, if within a bucket's width (a second for raw frames); null where it holds none.
 */
export function recordingValuesAt(answer: HistoryAnswer, traces: readonly TraceInfo[], time_ms: number): (TraceValue | null)[] | null {
  const t = answer.t;
  if (t.length === 0 || !Number.isFinite(time_ms)) return null;
  const time_s = time_ms / 1000;
  const width_s = answer.mode === "buckets" ? (answer.bucket_s ?? (answer.to - answer.from) / Math.max(1, answer.points)) : 1;
  // A bucket's time is its start: the cursor is in the last bucket starting at or before it.
  let lo = 0;
  let hi = t.length;
  while (lo < hi) {
    const mid = (lo + hi) >>> 1;
    if ((t[mid] as number) <= time_s) lo = mid + 1;
    else hi = mid;
  }
  let i = lo - 1;
  if (answer.mode === "raw" && lo < t.length && (i < 0 || (t[lo] as number) - time_s < time_s - (t[i] as number))) i = lo;
  if (i < 0 || Math.abs(time_s - (t[i] as number)) > width_s) return null;
  return traces.map((trace) => {
    const series = answer.series.find((s) => s.element === `${trace.fieldName}.${trace.channel}`);
    if (series === undefined) return null;
    if (answer.mode === "raw") {
      const v = finite(series.values?.[i]);
      return v === null ? null : { value: v };
    }
    const min = finite(series.min?.[i]);
    const max = finite(series.max?.[i]);
    if (min === null || max === null) return null;
    return min === max ? { value: min } : { min, max };
  });
}

/** A value as the readout shows it: four significant digits, a real minus sign. */
export function valueText(value: TraceValue | null): string {
  if (value === null) return "—";
  const one = (v: number) => {
    const text = Number(v.toPrecision(4)).toString();
    return text.startsWith("-") ? `\u2212${text.slice(1)}` : text;
  };
  return "value" in value ? one(value.value) : `${one(value.min)} … ${one(value.max)}`;
}
