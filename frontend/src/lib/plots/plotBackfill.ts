/**
 * Layer: a ring view's start from the recording (plain TypeScript; no DOM, no Plotly, no React).
 *
 * Just after the page opened (or a longer window was picked) the ring holds less than the
 * window: a 10 s window held 4 s and its axis stretched as the ring filled. A plot that reaches
 * the recording asks it once for the part of the window before the ring's oldest frame and draws
 * that in front of the ring's buckets, so the window is whole at once (docs/architecture.md
 * "Plots: one time axis for the panel"). The points are the answer's buckets, a minimum and a
 * maximum each (as the ring's own min/max buckets), a missing bucket a break in the line.
 * Must not import lib/plots/plotting.ts, Plotly or React.
 */
import type { TraceChunk } from "./decimate";
import type { HistoryAnswer, RangeData, TimeRange } from "./historyView";
import { BUCKETS_PER_WINDOW } from "./plotAppearance";
import { backfilledFrom_ms, unrecordedStart } from "./plotExport";
import { PlotRecording, type PlotHistorySource } from "./plotRecordingView";
import type { TraceInfo } from "./plots";
import type { SampleRing } from "../stream/ringBuffer";

type Datum = number | null;

/** The ring holds the window when it starts within this share of the window of its start. */
const WHOLE_SHARE = 0.02;

/**
 * The points of `answer` for `traces` before `before_ms` (ms since the epoch) and from the bucket
 * holding `from_ms` on, each bucket's minimum and maximum (a raw frame's value once), x shifted
 * by `shift_ms` as the plot's.
 */
export function backfillPoints(
  answer: HistoryAnswer,
  traces: readonly TraceInfo[],
  before_ms: number,
  shift_ms: number,
  from_ms = -Infinity,
): { xs: number[][]; ys: Datum[][] } {
  const buckets = answer.mode === "buckets";
  const width_s = buckets ? (answer.bucket_s ?? (answer.to - answer.from) / Math.max(1, answer.points)) : 0;
  const xs: number[][] = [];
  const ys: Datum[][] = [];
  for (const trace of traces) {
    const x: number[] = [];
    const y: Datum[] = [];
    const series = answer.series.find((s) => s.element === `${trace.fieldName}.${trace.channel}`);
    answer.t.forEach((t_s, i) => {
      if (series === undefined || t_s * 1000 >= before_ms || (t_s + width_s) * 1000 <= from_ms) return;
      const previous = answer.t[i - 1];
      // A bucket missing in between (no frames then): a break, never a bridge.
      if (buckets && previous !== undefined && x.length > 0 && t_s - previous > width_s * 1.5) {
        x.push(previous * 1000 + width_s * 1000 - shift_ms);
        y.push(null);
      }
      const at = t_s * 1000 - shift_ms;
      if (buckets) {
        x.push(at, at + (width_s * 1000) / 2);
        y.push(num(series.min?.[i]), num(series.max?.[i]));
      } else {
        x.push(at);
        y.push(num(series.values?.[i]));
      }
    });
    xs.push(x);
    ys.push(y);
  }
  return { xs, ys };
}

function num(v: number | boolean | null | undefined): Datum {
  if (typeof v === "boolean") return v ? 1 : 0;
  return typeof v === "number" && Number.isFinite(v) ? v : null;
}

/** A ring view's one request for the part of its window the ring does not hold yet. */
export class RingBackfill {
  private readonly loader: PlotRecording;
  private readonly ring: SampleRing;
  /** The window asked for (ms); null: none yet. */
  private askedFor_ms: number | null = null;
  private answer: HistoryAnswer | null = null;
  /** The range asked for (s since the epoch): the window's start before the ring's oldest frame. */
  private asked: TimeRange | null = null;

  /** `arrived`: an answer came (the ring view draws again). */
  constructor(source: PlotHistorySource, ring: SampleRing, arrived: () => void) {
    this.ring = ring;
    this.loader = new PlotRecording(source, {
      answered: (data: RangeData) => {
        this.answer = data.answer;
        arrived();
      },
      // Without it the window fills from the ring as before.
      failed: () => undefined,
      refreshDue: () => undefined,
    });
  }

  /** The recording's answer, while it covers some of the window (for the cursor's values too). */
  get data(): HistoryAnswer | null {
    return this.answer;
  }

  /**
   * Whether the `window_ms` window is yet to be judged (the ring held no frame when it was
   * drawn last): the ring view draws whole again at its next update to ask.
   */
  undecided(window_ms: number): boolean {
    return this.askedFor_ms !== window_ms && this.ring.newestTime() !== null;
  }

  /**
   * Ask once per window for what the ring lacks of a `window_ms` window ending at its newest
   * frame (nothing when it holds the window; judged again only for another window).
   */
  askIfShort(window_ms: number): void {
    if (this.askedFor_ms === window_ms) return;
    const newest = this.ring.newestTime();
    if (newest === null) return;
    this.askedFor_ms = window_ms;
    this.answer = null;
    const oldest = this.ring.timeAt(this.ring.oldestSeq);
    const from = newest - window_ms;
    if (oldest <= from + window_ms * WHOLE_SHARE) return;
    this.asked = { from_s: from / 1000, to_s: oldest / 1000 };
    // Buckets as wide as the ring view's, so the window holds its 400 points in all.
    const buckets = Math.max(1, Math.round((BUCKETS_PER_WINDOW * (oldest - from)) / window_ms));
    this.loader.request({ from, to: oldest }, buckets, true);
  }

  /**
   * `chunk` (the window's buckets from the ring) with the answer's points of the `window_ms`
   * window in front, x shifted by `shift_ms`. Once the ring holds the window the answer goes.
   */
  prepend(chunk: TraceChunk | null, traces: readonly TraceInfo[], shift_ms: number, window_ms: number): { xs: number[][]; ys: Datum[][] } | null {
    if (this.answer === null) return chunk;
    const newest = this.ring.newestTime();
    const from_ms = newest === null ? -Infinity : newest - window_ms;
    if (newest !== null && this.ring.timeAt(this.ring.oldestSeq) <= from_ms + window_ms * WHOLE_SHARE) {
      this.answer = null;
      return chunk;
    }
    const first = chunk?.xs.find((x) => x.length > 0)?.[0];
    const before_ms = first !== undefined ? first + shift_ms : (newest ?? Infinity);
    const back = backfillPoints(this.answer, traces, before_ms, shift_ms, from_ms);
    return {
      xs: traces.map((_, i) => [...(back.xs[i] ?? []), ...(chunk?.xs[i] ?? [])]),
      ys: traces.map((_, i) => [...(back.ys[i] ?? []), ...(chunk?.ys[i] ?? [])]),
    };
  }

  /**
   * Where the drawn `window_ms` window starts (ms since the epoch) while the recording fills its
   * front: the time axis shows it, an export of the view covers it; null: the ring's own start.
   */
  drawnFrom_ms(window_ms: number): number | null {
    const newest = this.ring.newestTime();
    return this.answer === null || newest === null ? null : backfilledFrom_ms(newest, window_ms, this.answer);
  }

  /** The part of the range asked for that the recording has nothing of (s since the epoch), or null. */
  unrecorded(): TimeRange | null {
    return this.answer === null || this.asked === null ? null : unrecordedStart(this.asked, this.answer);
  }

  stop(): void {
    this.loader.stopRequests();
  }
}
