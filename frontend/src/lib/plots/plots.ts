/**
 * Layer: pure plot definitions (no React, no DOM, no Plotly).
 *
 * Which frame fields each live plot shows, on which y axis. Units, channel labels and
 * descriptions are taken from the layout; only the grouping into plots and the short axis
 * words are UI decisions made here.
 */
import type { FieldInfo, FrameFieldName } from "../../generated/layout";
import { frameField } from "../layout/layoutInfo";

export interface PlotSeries {
  readonly field: FrameFieldName;
  /** Word on the axis before the unit, and before channel labels when a plot has two series. */
  readonly label: string;
  readonly axis: "y" | "y2";
}

export interface PlotSpec {
  /** Also the plot's data-testid. */
  readonly id: string;
  readonly title: string;
  readonly series: readonly PlotSeries[];
}

function single(id: string, title: string, field: FrameFieldName, label: string): PlotSpec {
  return { id, title, series: [{ field, label, axis: "y" }] };
}

export const JOINT_PLOTS: readonly PlotSpec[] = [
  single("plot-joint-position", "Joint position", "joint_position", "position"),
  single("plot-joint-velocity", "Joint velocity", "joint_velocity", "velocity"),
  single("plot-joint-motor-current", "Motor current", "joint_motor_current", "current"),
  single("plot-joint-motor-temperature", "Motor temperature", "joint_motor_temperature", "temperature"),
  single("plot-joint-torque", "Joint torque", "joint_torque", "torque"),
  single("plot-joint-external-torque", "External joint torque", "joint_external_torque", "external torque"),
];

export const TCP_PLOTS: readonly PlotSpec[] = [
  single("plot-tcp-position", "TCP position", "tcp_position", "position"),
  single("plot-tcp-orientation", "TCP orientation", "tcp_orientation", "orientation"),
  {
    id: "plot-tcp-velocity",
    title: "TCP velocity (linear and angular)",
    series: [
      { field: "tcp_velocity", label: "linear", axis: "y" },
      { field: "tcp_angular_velocity", label: "angular", axis: "y2" },
    ],
  },
  {
    id: "plot-external-force",
    title: "External force and moment",
    series: [
      { field: "external_force", label: "force", axis: "y" },
      { field: "external_moment", label: "moment", axis: "y2" },
    ],
  },
];

export const ALL_PLOTS: readonly PlotSpec[] = [...JOINT_PLOTS, ...TCP_PLOTS];

export interface TraceInfo {
  /** Trace name in the legend and the signal picker. */
  readonly name: string;
  readonly fieldName: FrameFieldName;
  readonly field: FieldInfo;
  readonly channel: number;
  readonly axis: "y" | "y2";
}

/** One trace per channel of each series, in order; names from the layout's channel labels. */
export function tracesOf(spec: PlotSpec): TraceInfo[] {
  const twoSeries = spec.series.length > 1;
  return spec.series.flatMap((s) => {
    const field = frameField(s.field);
    return field.channels.map((label, channel) => ({
      name: twoSeries ? `${s.label} ${label}` : label,
      fieldName: s.field,
      field,
      channel,
      axis: s.axis,
    }));
  });
}

/** Axis title with the layout's unit: "position [degree]". */
export function axisTitle(series: PlotSeries): string {
  const unit = frameField(series.field).unit;
  return unit === "" ? series.label : `${series.label} [${unit}]`;
}

/** The titles of a plot's y axes (right axis only for a plot with two series). */
export function axisTitles(spec: PlotSpec): { readonly y: string; readonly y2: string | null } {
  const y1 = spec.series.find((s) => s.axis === "y");
  const y2 = spec.series.find((s) => s.axis === "y2");
  return { y: y1 === undefined ? "" : axisTitle(y1), y2: y2 === undefined ? null : axisTitle(y2) };
}

/** Trace colours (colour-blind friendly order, Okabe–Ito). */
export const TRACE_COLOURS: readonly string[] = [
  "#0072B2",
  "#E69F00",
  "#009E73",
  "#CC79A7",
  "#56B4E9",
  "#D55E00",
];

export function traceColour(i: number): string {
  return TRACE_COLOURS[i % TRACE_COLOURS.length] as string;
}

/** The plot window lengths a person can choose. */
export const WINDOWS_MS: readonly { readonly label: string; readonly ms: number }[] = [
  { label: "10 s", ms: 10_000 },
  { label: "30 s", ms: 30_000 },
  { label: "2 min", ms: 120_000 },
];
export const DEFAULT_WINDOW_MS = 10_000;
/** The longest window drawn from the ring alone; longer ones come from the recording. */
export const RING_WINDOW_MAX_MS = 120_000;

/**
 * The long windows of a plot that can reach the recording (the panel's, not the kiosk's): moving
 * windows drawn from the history API, refreshed as they move, the newest seconds from the ring.
 */
export const HISTORY_WINDOWS_MS: readonly { readonly label: string; readonly ms: number }[] = [
  { label: "15 min", ms: 15 * 60_000 },
  { label: "1 h", ms: 3_600_000 },
  { label: "24 h", ms: 24 * 3_600_000 },
  { label: "7 days", ms: 7 * 24 * 3_600_000 },
];

/**
 * The ring's channel map: every plotted field gets `count` consecutive channels. Built from the
 * plot definitions so a field no plot shows is not buffered.
 */
export class ChannelMap {
  readonly base: ReadonlyMap<FrameFieldName, number>;
  readonly fields: readonly FrameFieldName[];
  readonly channelCount: number;

  constructor(specs: readonly PlotSpec[]) {
    const base = new Map<FrameFieldName, number>();
    let next = 0;
    for (const spec of specs) {
      for (const s of spec.series) {
        if (base.has(s.field)) continue;
        base.set(s.field, next);
        next += frameField(s.field).count;
      }
    }
    this.base = base;
    this.fields = [...base.keys()];
    this.channelCount = next;
  }

  /** Ring channel of channel `channel` of `field`. */
  channelOf(field: FrameFieldName, channel: number): number {
    const b = this.base.get(field);
    if (b === undefined) throw new Error(`field ${field} is not buffered`);
    return b + channel;
  }
}
