/**
 * Layer: the weekly health report (no React, no DOM): the week it covers, its CSV download link
 * (the service's `…/health/report.csv`, fetched by the browser with the session cookie) and the
 * printed page's title. The page printed is the report's other form (styles/health.css, print).
 */
import { formatDateTime_ms } from "../common/dates";

export const WEEK_S = 7 * 24 * 3600;

export interface ReportWeek {
  readonly from_s: number;
  readonly to_s: number;
}

/** The week ending at `now_ms` (whole seconds). */
export function lastWeek(now_ms: number): ReportWeek {
  const to_s = Math.floor(now_ms / 1000);
  return { from_s: to_s - WEEK_S, to_s };
}

/** The CSV of the robot's health over `week` (a download link). */
export function reportCsvUrl(robot: string, week: ReportWeek): string {
  const q = new URLSearchParams({ from: String(week.from_s), to: String(week.to_s) });
  return `/api/v1/robots/${encodeURIComponent(robot)}/health/report.csv?${q.toString()}`;
}

/** The file name the browser saves the CSV under. */
export function reportCsvName(robot: string, week: ReportWeek): string {
  const day = new Date(week.to_s * 1000).toISOString().slice(0, 10);
  return `health-${robot}-${day}.csv`;
}

/** "Weekly health report of m1013, 2026-11-30 14:00:00 – 2026-12-07 14:00:00" in the site's time zone. */
export function reportTitle(robot: string, week: ReportWeek, zone?: string): string {
  return `Weekly health report of ${robot}, ${formatDateTime_ms(week.from_s * 1000, false, zone)} – ${formatDateTime_ms(week.to_s * 1000, false, zone)}`;
}
