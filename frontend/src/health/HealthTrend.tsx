/**
 * The robot's health over days: one line per joint of the figure chosen (friction against its
 * baseline, heat beyond its current, life used), from the service's snapshots
 * (`…/health/trend`), the moments a new baseline came into use marked. Drawn with Plotly
 * (lib/plots/plotlyAdapter.ts) straight from the answer: the points never pass through React
 * state, which holds only the choices and what to say about the answer.
 */
import { useEffect, useMemo, useRef, useState } from "react";
import { healthApi } from "../lib/health/healthApi";
import type { TrendAnswer } from "../lib/health/healthTypes";
import { TREND_DAYS, TREND_FIGURES, trendRange, trendSeries, type TrendFigure } from "../lib/health/trend";
import type { PlotTheme } from "../lib/plots/plotAppearance";
import { plotlyBackend } from "../lib/plots/plotlyAdapter";
import { PlotlyOnDemand } from "../lib/plots/plotlyOnDemand";

/** The snapshots come every few minutes: asked again this often while the page is open. */
const TREND_REFRESH_MS = 60_000;

const JOINT_COLOURS = ["#1f5fbf", "#c2410c", "#15803d", "#7e22ce", "#b91c1c", "#0e7490"];

function drawTrend(el: HTMLElement, answer: TrendAnswer | null, figure: TrendFigure, theme: PlotTheme): number {
  const series = trendSeries(answer, figure);
  const text = theme === "dark" ? "#ddd" : "#222";
  const grid = theme === "dark" ? "#444" : "#ddd";
  const traces = series.joints.map((s, i) => ({
    type: "scatter",
    mode: "lines+markers",
    name: `J${s.joint}`,
    x: s.x.map((x) => new Date(x)),
    y: s.y,
    connectgaps: false,
    line: { color: JOINT_COLOURS[i % JOINT_COLOURS.length], width: 2 },
    marker: { size: 4 },
  }));
  const shapes = series.baselineChanges.map((c) => ({
    type: "line",
    xref: "x",
    yref: "paper",
    x0: new Date(c.x),
    x1: new Date(c.x),
    y0: 0,
    y1: 1,
    line: { color: text, dash: "dot", width: 1 },
  }));
  const annotations = series.baselineChanges.map((c) => ({ x: new Date(c.x), y: 1, xref: "x", yref: "paper", text: `baseline ${c.id}`, showarrow: false, yanchor: "bottom", font: { size: 11, color: text } }));
  plotlyBackend.react(
    el,
    traces,
    {
      height: 300,
      margin: { l: 60, r: 16, t: 24, b: 44 },
      paper_bgcolor: "rgba(0,0,0,0)",
      plot_bgcolor: "rgba(0,0,0,0)",
      font: { color: text },
      xaxis: { type: "date", gridcolor: grid },
      yaxis: { title: { text: TREND_FIGURES[figure] }, gridcolor: grid, zeroline: true, zerolinecolor: grid },
      legend: { orientation: "h", y: -0.2 },
      shapes,
      annotations,
    },
    { displaylogo: false, responsive: true },
  );
  return series.points;
}

export function HealthTrend({ robot, theme }: { readonly robot: string; readonly theme: PlotTheme }) {
  const plot = useRef<HTMLDivElement>(null);
  const answer = useRef<TrendAnswer | null>(null);
  const [days, setDays] = useState<number>(7);
  const [figure, setFigure] = useState<TrendFigure>("friction_percent");
  // What the page says about the answer (never its points): how many snapshots, or why none.
  const [status, setStatus] = useState<{ points: number | null; error: string | null }>({ points: null, error: null });
  const [received, setReceived] = useState(0);
  const [plotlyCame, setPlotlyCame] = useState(false);
  const plotly = useMemo(() => new PlotlyOnDemand(plotlyBackend, () => setPlotlyCame(true)), []);

  useEffect(() => {
    let cancelled = false;
    const load = () => {
      const range = trendRange(Date.now(), days);
      healthApi
        .trend(robot, range.from_s, range.to_s)
        .then((result) => {
          if (cancelled) return;
          if (result.ok) {
            answer.current = result.value;
            setStatus({ points: result.value.points.length, error: null });
          } else {
            setStatus((s) => ({ ...s, error: result.reason }));
          }
          setReceived((n) => n + 1);
        })
        .catch((error: unknown) => {
          if (!cancelled) setStatus((s) => ({ ...s, error: error instanceof Error ? error.message : String(error) }));
        });
    };
    load();
    const timer = setInterval(load, TREND_REFRESH_MS);
    return () => {
      cancelled = true;
      clearInterval(timer);
    };
  }, [robot, days]);

  useEffect(() => {
    if (plot.current === null || !plotly.ready()) return;
    drawTrend(plot.current, answer.current, figure, theme);
  }, [received, figure, theme, plotly, plotlyCame]);

  useEffect(() => {
    const el = plot.current;
    return () => {
      if (el !== null) plotlyBackend.purge(el);
    };
  }, []);

  return (
    <div className="health-trend">
      <div className="health-trend__controls no-print">
        <label>
          figure{" "}
          <select value={figure} onChange={(e) => setFigure(e.target.value as TrendFigure)} data-testid="health-trend-figure">
            {Object.entries(TREND_FIGURES).map(([key, words]) => (
              <option key={key} value={key}>
                {words}
              </option>
            ))}
          </select>
        </label>
        <label>
          over{" "}
          <select value={days} onChange={(e) => setDays(Number(e.target.value))} data-testid="health-trend-days">
            {TREND_DAYS.map((d) => (
              <option key={d} value={d}>
                {d === 1 ? "the last day" : `the last ${d} days`}
              </option>
            ))}
          </select>
        </label>
      </div>
      <div ref={plot} className="health-trend__plot" data-testid="health-trend" data-points={status.points ?? ""} role="figure" aria-label={`${TREND_FIGURES[figure]} per joint over the last ${days} day(s)`} />
      <p className="hint" data-testid="health-trend-status">
        {status.error !== null
          ? `The trend could not be read: ${status.error}`
          : status.points === null
            ? "Asking the service for the trend…"
            : status.points === 0
              ? "No snapshot in this range yet: the service keeps one every few minutes."
              : `${status.points} snapshot${status.points === 1 ? "" : "s"}.`}
      </p>
    </div>
  );
}
