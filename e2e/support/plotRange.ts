/** What a live plot of the panel shows, read from the page (components/LivePlotView.tsx). */
import type { Locator } from "@playwright/test";

/**
 * The x range a plot shows (ms since the epoch): the canvas picture's (its data attributes)
 * while nobody points at it, Plotly's layout when it is interactive (issue 24).
 */
export async function shownRange(plot: Locator): Promise<[number, number]> {
  return plot.evaluate((el) => {
    const e = el as HTMLElement & { _fullLayout?: { xaxis?: { range?: unknown[] } } };
    if (e.dataset.renderer === "canvas") return [Number(e.dataset.xFrom), Number(e.dataset.xTo)] as [number, number];
    // Numeric dates are local time shown as UTC (the plots' shift); text ones read as UTC.
    const tz = new Date().getTimezoneOffset() * 60_000;
    const range = e._fullLayout?.xaxis?.range ?? [];
    return range.map((v) => (typeof v === "number" ? v : new Date(String(v).replace(" ", "T") + "Z").getTime()) + tz) as [number, number];
  });
}
