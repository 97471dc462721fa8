/**
 * Layer: the health trend's data (no React, no DOM): the service's snapshots of a robot's
 * figures over a range (`GET …/health/trend?from=&to=`) as one series per joint of the figure
 * chosen, with gaps where a joint had no figure, and the moments a new baseline came into use
 * (the trend spans them: docs/health.md "Baseline").
 */
import type { TrendAnswer } from "./healthTypes";

/** The figures a trend can show, each with its axis title. */
export const TREND_FIGURES = {
  friction_percent: "friction against its baseline (%)",
  heat_excess_c: "heat beyond its current (°C)",
  life_used_percent: "reducer life used (%)",
} as const;

export type TrendFigure = keyof typeof TREND_FIGURES;

export interface JointSeries {
  readonly joint: number;
  /** ms since the epoch. */
  readonly x: readonly number[];
  /** null: no figure at that moment (a gap in the line). */
  readonly y: readonly (number | null)[];
}

export interface TrendSeries {
  readonly joints: readonly JointSeries[];
  /** When a baseline other than the one before came into use (ms since the epoch) and its id. */
  readonly baselineChanges: readonly { readonly x: number; readonly id: number }[];
  readonly points: number;
}

/** The figure's series for every joint the points name, J1 first, in time order. */
export function trendSeries(answer: TrendAnswer | null, figure: TrendFigure): TrendSeries {
  const points = [...(answer?.points ?? [])].sort((a, b) => a.time - b.time);
  const joints = new Map<number, { x: number[]; y: (number | null)[] }>();
  const baselineChanges: { x: number; id: number }[] = [];
  let baseline: number | null = null;
  for (const point of points) {
    const x = point.time * 1000;
    const id = point.baseline_id ?? null;
    if (id !== null && baseline !== null && id !== baseline) baselineChanges.push({ x, id });
    if (id !== null) baseline = id;
    for (const joint of point.joints) {
      const series = joints.get(joint.joint) ?? { x: [], y: [] };
      const value = joint[figure];
      series.x.push(x);
      series.y.push(typeof value === "number" && Number.isFinite(value) ? value : null);
      joints.set(joint.joint, series);
    }
  }
  return {
    joints: [...joints.entries()].sort(([a], [b]) => a - b).map(([joint, s]) => ({ joint, x: s.x, y: s.y })),
    baselineChanges,
    points: points.length,
  };
}

/** The ranges a person picks the trend over, in days. */
export const TREND_DAYS = [1, 7, 30, 90] as const;

export function trendRange(now_ms: number, days: number): { readonly from_s: number; readonly to_s: number } {
  const to_s = Math.floor(now_ms / 1000);
  return { from_s: to_s - days * 24 * 3600, to_s };
}
