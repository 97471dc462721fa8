/**
 * Layer: the DOM of a plot's cursor readout (no React, no Plotly).
 *
 * The panel's one cursor (lib/plots/timeRange.ts): the time a person points at on any plot, by the
 * pointer or by Shift + ← / →. Each plot shows, under its plotting area, that time and the value
 * of each of its signals then with its unit, and a line across the plot at that time. The values
 * are read from the ring (or the recording's answer the plot drew) where they are
 * (lib/plots/plotValues.ts) and written into the DOM here: samples never pass through React state.
 */
import { formatClock } from "../lib/common/dates";
import { valueText, type TraceValue } from "../lib/plots/plotValues";
import type { PlotMargin } from "../lib/plots/plotAppearance";
import type { SpanMs } from "../lib/plots/plotSteps";
import type { TraceInfo } from "../lib/plots/plots";
import { shareOfRange } from "./plotPointer";

/** What the readout reads (a live plot: lib/plots/plotting.ts `LivePlot`). */
export interface CursorSource {
  valuesAt(time_ms: number): readonly (TraceValue | null)[];
  shownRange(): SpanMs | null;
}

/** The readout's text of one signal: "J 1 12.35 degree". */
export function signalText(trace: TraceInfo, value: TraceValue | null): string {
  const unit = trace.field.unit;
  return `${trace.name} ${valueText(value)}${value !== null && unit !== "" ? ` ${unit}` : ""}`;
}

/** "07:21:04.737": the cursor's time to the millisecond, in the site's time zone. */
export function cursorTimeText(time_ms: number): string {
  const ms = String(Math.floor(((time_ms % 1000) + 1000) % 1000)).padStart(3, "0");
  return `${formatClock(time_ms)}.${ms}`;
}

export class CursorReadout {
  private readonly out: HTMLElement;
  private readonly line: HTMLElement;
  private readonly source: CursorSource;
  private readonly traces: readonly TraceInfo[];
  private readonly margin: PlotMargin;
  private readonly timeText: HTMLElement;
  private readonly valueTexts: HTMLElement[];
  private time_ms: number | null = null;

  /** `out`: the readout's element (its content made here); `line`: the line across the plot. */
  constructor(out: HTMLElement, line: HTMLElement, source: CursorSource, traces: readonly TraceInfo[], margin: PlotMargin, testId: string) {
    this.out = out;
    this.line = line;
    this.source = source;
    this.traces = traces;
    this.margin = margin;
    const doc = out.ownerDocument;
    out.replaceChildren();
    this.timeText = doc.createElement("span");
    this.timeText.className = "plot__cursor-time";
    out.append(this.timeText);
    this.valueTexts = traces.map((_, i) => {
      const span = doc.createElement("span");
      span.className = "plot__cursor-value";
      span.dataset.testid = `${testId}-cursor-${i}`;
      out.append(" ", span);
      return span;
    });
    this.show(null);
  }

  /** The cursor's time now (ms since the epoch), or null when none. */
  get time(): number | null {
    return this.time_ms;
  }

  /** Show the values at `time_ms`, or hide the readout (null). */
  show(time_ms: number | null): void {
    this.time_ms = time_ms;
    this.refresh();
  }

  /** Read the values again (the plot drew: the ring or the recording may hold more now). */
  refresh(): void {
    const time = this.time_ms;
    if (time === null) {
      this.out.hidden = true;
      delete this.out.dataset.time;
      this.line.hidden = true;
      return;
    }
    const values = this.source.valuesAt(time);
    this.out.hidden = false;
    this.out.dataset.time = String(time);
    this.timeText.textContent = cursorTimeText(time);
    this.traces.forEach((trace, i) => {
      const span = this.valueTexts[i];
      if (span !== undefined) span.textContent = signalText(trace, values[i] ?? null);
    });
    const at = shareOfRange(time, this.source.shownRange());
    this.line.hidden = at === null;
    if (at !== null) {
      const m = this.margin;
      this.line.style.left = `calc(${m.l}px + (100% - ${m.l + m.r}px) * ${at})`;
      this.line.style.top = `${m.t}px`;
      this.line.style.bottom = `${m.b}px`;
    }
  }
}
