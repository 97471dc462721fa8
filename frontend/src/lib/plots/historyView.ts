/**
 * Layer: the plots' way into the recording, independent of React and Plotly (plain TypeScript).
 *
 * A live plot (lib/plots/plotting.ts) that shows more than its ring holds — a long moving window
 * (15 min … 7 days), or a range of the past after a zoom, a pan, a custom range or a click on a
 * marker — draws the recorder's frames (docs/api.md "History"). Ranges are fetched decimated to
 * about one bucket per pixel (min/max per bucket, so every peak stays drawn as an envelope),
 * debounced while the view moves, a stale request cancelled with its AbortController. Events
 * and alarms of the range become markers on the time axis; the export links name the range.
 * Times here are seconds since the epoch, as the service's answers have them.
 */
import type { components } from "../../generated/api";
import { LAYOUT } from "../../generated/layout";
import { traceColour, tracesOf, type PlotSpec } from "./plots";

export type HistoryAnswer = components["schemas"]["HistoryAnswer"];
export type HistoryEvents = components["schemas"]["HistoryEvents"];
export type HistoryEvent = HistoryEvents["items"][number];

export interface TimeRange {
  readonly from_s: number;
  readonly to_s: number;
}

/** A custom range, or why not. */
export function customRange(from_s: number, to_s: number): TimeRange | string {
  if (!Number.isFinite(from_s) || !Number.isFinite(to_s)) return "Both times are needed.";
  if (to_s <= from_s) return "The end must be after the start.";
  return { from_s, to_s };
}

/** Where a click on a marker jumps: `margin_s` (default 30 s) before its first event and after its last. */
export function rangeOfMarker(marker: { readonly time_s: number; readonly last_s: number }, margin_s = 30): TimeRange {
  return { from_s: marker.time_s - margin_s, to_s: marker.last_s + margin_s };
}

export const MAX_POINTS = 5000;
const MIN_POINTS = 50;

/** Buckets to ask for: one per pixel of the plotting area (the service allows 1–5000). */
export function bucketsForWidth(width_px: number): number {
  if (!Number.isFinite(width_px)) return 1000;
  return Math.min(MAX_POINTS, Math.max(MIN_POINTS, Math.round(width_px)));
}

/** The fields of a plot, as the history API's `fields` parameter. */
export function fieldsOf(spec: PlotSpec): string {
  return [...new Set(spec.series.map((s) => s.field))].join(",");
}

// ---- Plotly traces (plain objects; numeric dates, shifted to local time as the live plots do)

type Datum = number | null;

function num(v: boolean | number | null | undefined): Datum {
  if (v === null || v === undefined) return null;
  return typeof v === "boolean" ? (v ? 1 : 0) : v;
}

/**
 * The answer's traces for `spec`, per trace of the plot (`tracesOf(spec)`'s order): per element,
 * a min and a max line with the band between filled (mode buckets), or the values (mode raw).
 * A gap in the recording (a missing bucket, or raw frames further apart than a second) breaks
 * the lines instead of bridging it. `shift_ms` is subtracted from every time (Plotly shows
 * numeric dates in UTC).
 */
export function envelopeTraceSets(answer: HistoryAnswer, spec: PlotSpec, shift_ms: number): object[][] {
  const traces = tracesOf(spec);
  const step_s = answer.mode === "buckets" ? (answer.bucket_s ?? (answer.to - answer.from) / Math.max(1, answer.points)) : 1;
  const gapAfter: boolean[] = answer.t.map((t, i) => {
    const next = answer.t[i + 1];
    return next !== undefined && next - t > step_s * 1.5;
  });
  const withGaps = (values: readonly Datum[]): { x: Datum[]; y: Datum[] } => {
    const x: Datum[] = [];
    const y: Datum[] = [];
    answer.t.forEach((t, i) => {
      x.push(t * 1000 - shift_ms);
      y.push(values[i] ?? null);
      if (gapAfter[i] === true) {
        x.push(t * 1000 - shift_ms + 1);
        y.push(null);
      }
    });
    return { x, y };
  };
  return traces.map((trace, i) => {
    const element = `${trace.fieldName}.${trace.channel}`;
    const series = answer.series.find((s) => s.element === element);
    if (series === undefined) return [];
    const colour = traceColour(i);
    const base = { type: "scatter", mode: "lines", yaxis: trace.axis, connectgaps: false, showlegend: false };
    const unit = series.unit;
    if (answer.mode === "raw") {
      return [
        {
          ...base,
          name: trace.name,
          ...withGaps((series.values ?? []).map(num)),
          line: { width: 1.5, color: colour },
          hovertemplate: `${trace.name}: %{y:.4~r} ${unit}<extra></extra>`,
        },
      ];
    }
    return [
      {
        ...base,
        name: `${trace.name} min`,
        ...withGaps((series.min ?? []).map(num)),
        line: { width: 1, color: colour },
        hovertemplate: `${trace.name} min: %{y:.4~r} ${unit}<extra></extra>`,
      },
      {
        ...base,
        name: `${trace.name} max`,
        ...withGaps((series.max ?? []).map(num)),
        line: { width: 1, color: colour },
        fill: "tonexty",
        fillcolor: `${colour}40`,
        hovertemplate: `${trace.name} max: %{y:.4~r} ${unit}<extra></extra>`,
      },
    ];
  });
}

/**
 * The time (s) of the newest frame the answer holds, or null when it holds none: what comes
 * after it in the range the plot takes from its ring (frames the recorder has not written yet).
 */
export function newestRecorded(answer: HistoryAnswer): number | null {
  if (answer.frames === 0 || answer.t.length === 0) return null;
  const last = answer.t_last ?? answer.t;
  let newest = -Infinity;
  for (const t of last) if (t > newest) newest = t;
  return Number.isFinite(newest) ? newest : null;
}

// ---- Markers

export interface MarkerEvent {
  readonly time_s: number;
  readonly kind: HistoryEvent["kind"];
  readonly label: string;
  /** An alarm or an emergency stop: its marker is drawn as urgent ("▲!"). */
  readonly urgent: boolean;
}

/** One marker: an event, or events too close together to tell apart at this zoom. */
export interface Marker {
  readonly id: string;
  /** The first event's time. */
  readonly time_s: number;
  /** The last event's time (the first's, for a marker of one event). */
  readonly last_s: number;
  /** "alarm" when any of its events is an alarm or an emergency stop, else the first's kind. */
  readonly kind: HistoryEvent["kind"];
  /** Its events' words, oldest first, "; " between. */
  readonly label: string;
  readonly events: readonly MarkerEvent[];
  /** Position within the plotting area, 0–1. */
  readonly at: number;
}

/** Events closer than this (a share of the plotting area's width) share one marker. */
export const MARKER_SPACING = 0.015;
/** A marker button's width and a gap (px): markers closer than this on screen share one. */
export const MARKER_WIDTH_PX = 30;
/** The same on a touch screen, where a marker is a 44 px target (styles/responsive.css). */
export const MARKER_WIDTH_TOUCH_PX = 48;

/** The spacing of markers `marker_px` wide on a plotting area `width_px` wide. */
export function markerSpacing(width_px: number, marker_px = MARKER_WIDTH_PX): number {
  return width_px > 0 ? Math.max(MARKER_SPACING, marker_px / width_px) : MARKER_SPACING;
}

const STATE_WORDS = new Map<string, string>(LAYOUT.robot_states.map((s) => [s.name, s.label]));

/** An alarm's transition as the service's event text says it (service/events/text.py). */
const TRANSITION_WORDS: Readonly<Record<string, string>> = {
  activated: "activated",
  cleared: "returned to normal",
  acknowledged: "acknowledged",
  shelved: "shelved",
  unshelved: "unshelved",
  shelve_expired: "unshelved (shelving expired)",
};

/** The words of an event on its marker: never a state's or a transition's code. */
export function eventLabel(event: HistoryEvent): string {
  switch (event.kind) {
    case "robot_state":
      return `Robot state ${STATE_WORDS.get(event.to_name) ?? `${event.to} (unknown)`}`;
    case "alarm":
      return `${event.alarm.name} ${TRANSITION_WORDS[event.transition] ?? event.transition.replace(/_/g, " ")}`;
    case "cycle":
      return `Cycle ${event.duration_s.toFixed(2)} s`;
    default:
      // The service's own words ("Connection connected", "Recording resumed").
      return typeof event.text === "string" && event.text !== "" ? event.text : event.kind.replace("_", " ");
  }
}

/** Kinds shown as markers: what explains a curve (not every write or control hand-over), and
 * each cycle's start (the robot's cycle trigger). */
export const MARKER_KINDS: readonly HistoryEvent["kind"][] = ["robot_state", "alarm", "connection", "recording", "cycle"];

function isUrgent(e: HistoryEvent): boolean {
  return e.kind === "alarm" || (e.kind === "robot_state" && e.to_name === "EMERGENCY_STOP");
}

const urgent = (e: MarkerEvent) => e.urgent;

/**
 * The events of `range` as markers placed on the time axis (a fraction of the plotting area).
 * The area is cut into bins `spacing` wide (MARKER_SPACING, or a marker's width on a narrow
 * plot), counted from the range's start: the events of a bin share its marker, so which marker
 * an event is in depends on its own time and the range only — not on the events around it. A
 * marker grouped by its neighbours would change its first event when an answer with more events
 * of the range's start comes in, and a click a moment later would jump elsewhere than the marker
 * read. Each marker sits at its first event, pushed right just enough not to cover the one
 * before (never past its bin's end), so markers never overlap and each can be clicked. Zooming
 * in separates them.
 */
export function markersOf(events: readonly HistoryEvent[], range: TimeRange, spacing = MARKER_SPACING): Marker[] {
  const span = range.to_s - range.from_s;
  if (!(span > 0) || !(spacing > 0)) return [];
  const bins = new Map<number, { first: HistoryEvent; at: number; events: MarkerEvent[] }>();
  for (const e of events) {
    if (!MARKER_KINDS.includes(e.kind) || e.time < range.from_s || e.time >= range.to_s) continue;
    const at = (e.time - range.from_s) / span;
    const bin = Math.floor(at / spacing);
    const item = { time_s: e.time, kind: e.kind, label: eventLabel(e), urgent: isUrgent(e) };
    const group = bins.get(bin);
    if (group === undefined) bins.set(bin, { first: e, at, events: [item] });
    else if (e.time < group.first.time) {
      // (The log answers oldest first; an out-of-order event still leads its bin.)
      group.first = e;
      group.at = at;
      group.events.unshift(item);
    } else group.events.push(item);
  }
  const markers: Marker[] = [];
  let previousAt = -Infinity;
  for (const [, g] of [...bins.entries()].sort(([a], [b]) => a - b)) {
    const at = Math.max(g.at, previousAt + spacing);
    previousAt = at;
    markers.push({
      id: `${g.first.id ?? markers.length}-${g.first.time}`,
      time_s: g.first.time,
      last_s: g.events[g.events.length - 1]?.time_s ?? g.first.time,
      kind: g.events.some(urgent) ? "alarm" : g.first.kind,
      label: g.events.map((e) => e.label).join("; "),
      events: g.events,
      at,
    });
  }
  return markers;
}

// ---- Export

export type ExportFormat = "csv" | "parquet" | "mcap";
export const EXPORT_FORMATS: readonly ExportFormat[] = ["csv", "parquet", "mcap"];

/** The export link of a range (a plain download: the browser sends the session cookie). */
export function exportUrl(robot: string, range: TimeRange, format: ExportFormat, fields: string | null): string {
  const q = new URLSearchParams({ from: range.from_s.toFixed(3), to: range.to_s.toFixed(3), format });
  if (fields !== null && fields !== "") q.set("fields", fields);
  return `/api/v1/robots/${encodeURIComponent(robot)}/export?${q.toString()}`;
}

// ---- Fetching

export interface RangeData {
  readonly range: TimeRange;
  readonly answer: HistoryAnswer;
  readonly events: readonly HistoryEvent[];
}

export type FetchRange = (range: TimeRange, points: number, signal: AbortSignal) => Promise<RangeData>;

export interface Timer {
  set(callback: () => void, delay_ms: number): unknown;
  clear(handle: unknown): void;
}

export const browserTimer: Timer = {
  set: (cb, ms) => setTimeout(cb, ms),
  clear: (h) => clearTimeout(h as ReturnType<typeof setTimeout>),
};

/**
 * Asks for ranges as the view moves: the last request within `debounce_ms` wins; a newer
 * request aborts the one in flight, whose answer is never delivered.
 */
export class RangeLoader {
  private pending: unknown = null;
  private inFlight: AbortController | null = null;
  private generation = 0;

  constructor(
    private readonly fetchRange: FetchRange,
    private readonly onData: (data: RangeData) => void,
    private readonly onError: (reason: string) => void,
    private readonly debounce_ms = 200,
    private readonly timer: Timer = browserTimer,
  ) {}

  request(range: TimeRange, points: number, immediate = false): void {
    if (this.pending !== null) this.timer.clear(this.pending);
    this.pending = null;
    if (immediate) {
      this.start(range, points);
      return;
    }
    this.pending = this.timer.set(() => {
      this.pending = null;
      this.start(range, points);
    }, this.debounce_ms);
  }

  private start(range: TimeRange, points: number): void {
    this.inFlight?.abort();
    const controller = new AbortController();
    this.inFlight = controller;
    const generation = ++this.generation;
    this.fetchRange(range, points, controller.signal).then(
      (data) => {
        if (generation !== this.generation || controller.signal.aborted) return;
        this.inFlight = null;
        this.onData(data);
      },
      (error: unknown) => {
        if (generation !== this.generation || controller.signal.aborted) return;
        this.inFlight = null;
        this.onError(error instanceof Error ? error.message : String(error));
      },
    );
  }

  /** Nothing more is delivered. */
  stop(): void {
    if (this.pending !== null) this.timer.clear(this.pending);
    this.pending = null;
    this.inFlight?.abort();
    this.inFlight = null;
    this.generation++;
  }
}

/** A Plotly date-axis value (a number, or its "2026-11-24 07:00:00.123" text, UTC) as epoch s. */
export function axisTimeToEpochS(value: unknown, shift_ms: number): number {
  if (typeof value === "number") return (value + shift_ms) / 1000;
  if (typeof value === "string") return (Date.parse(`${value.trim().replace(" ", "T")}Z`) + shift_ms) / 1000;
  return Number.NaN;
}
