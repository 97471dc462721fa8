/**
 * Cycle timing of the robot shown (docs/operations.md "Cycle timing"): what starts a cycle, the
 * last one, the mean, minimum and maximum of the newest N, a trend of the durations and their
 * histogram (Plotly, through lib/plots/plotlyAdapter), the newest cycles as a table, the CSV export and
 * a printed page of the statistics. Asked again every few seconds: a cycle lasts seconds.
 * Interrupted cycles (the robot stopped, lost its link or left its running states) are listed
 * apart with what interrupted them and left out of the statistics, the trend and the histogram,
 * unless "include interrupted cycles" is ticked.
 */
import { memo, useEffect, useMemo, useRef, useState } from "react";
import { api } from "../lib/api/api";
import {
  CYCLE_WINDOW,
  CYCLES_SHOWN,
  cyclesCsvUrl,
  fetchCycles,
  formatCycle_s,
  histogram,
  interruptedWords,
  splitCycles,
  type CyclePage,
  type CycleRow,
} from "../lib/history/cycles";
import { formatTimestamp } from "../lib/common/dates";
import type { PlotTheme } from "../lib/plots/plotAppearance";
import { plotlyBackend } from "../lib/plots/plotlyAdapter";
import { PlotlyOnDemand } from "../lib/plots/plotlyOnDemand";
import { printSection } from "../lib/history/searchPrint";
import "../styles/cycles.css";

const POLL_MS = 2000;
const TABLE_ROWS = 20;

function colours(theme: PlotTheme) {
  return theme === "dark" ? { text: "#ddd", grid: "#444", trace: "#4fa3ff" } : { text: "#222", grid: "#ddd", trace: "#1f5fbf" };
}

function layoutOf(theme: PlotTheme, xTitle: string, yTitle: string, xType: "date" | "linear") {
  const c = colours(theme);
  return {
    height: 260,
    margin: { l: 56, r: 16, t: 12, b: 44 },
    paper_bgcolor: "rgba(0,0,0,0)",
    plot_bgcolor: "rgba(0,0,0,0)",
    font: { color: c.text },
    xaxis: { title: { text: xTitle }, type: xType, gridcolor: c.grid },
    yaxis: { title: { text: yTitle }, gridcolor: c.grid, rangemode: "tozero" },
    showlegend: false,
  };
}

const CONFIG = { displaylogo: false, responsive: true };

/** The plots are drawn again when this near the screen (an IntersectionObserver's margin). */
const NEAR_MARGIN = "300px 0px";

/** The trend and the histogram, drawn into their own elements (no samples in React state). */
function CyclePlots({ cycles, theme }: { readonly cycles: readonly CycleRow[]; readonly theme: PlotTheme }) {
  const trend = useRef<HTMLDivElement>(null);
  const bars = useRef<HTMLDivElement>(null);
  const grid = useRef<HTMLDivElement>(null);
  // What was drawn: the page is asked again every 2 s and mostly brings the same cycles, and
  // Plotly redraws (and measures) both plots whole, about 100 ms of the main thread here.
  const drawn = useRef("");
  // The plots are drawn when they come near the screen (or the page is printed) with cycles
  // they have not drawn: below the fold nothing, not even Plotly's chunk (lib/plots/plotlyAdapter.ts),
  // which is asked for the first time they come near.
  const [near, setNear] = useState(() => typeof IntersectionObserver === "undefined");
  // Plotly asked for as the live plots ask (lib/plots/plotlyOnDemand.ts): once, and again at the next
  // drawing after a failed load; `plotlyCame` draws what waited for it.
  const [plotlyCame, setPlotlyCame] = useState(false);
  const plotly = useMemo(() => new PlotlyOnDemand(plotlyBackend, () => setPlotlyCame(true)), []);
  useEffect(() => {
    const target = grid.current;
    if (target === null || typeof IntersectionObserver === "undefined") return;
    const observer = new IntersectionObserver((entries) => setNear(entries.some((e) => e.isIntersecting)), { rootMargin: NEAR_MARGIN });
    observer.observe(target);
    const beforePrint = () => setNear(true);
    window.addEventListener("beforeprint", beforePrint);
    return () => {
      observer.disconnect();
      window.removeEventListener("beforeprint", beforePrint);
    };
  }, []);
  useEffect(() => {
    const key = `${theme} ${cycles.map((c) => c.id).join(",")}`;
    if (key === drawn.current || !near || !plotly.ready()) return;
    drawn.current = key;
    const durations = cycles.map((c) => c.duration_s);
    const c = colours(theme);
    if (trend.current !== null) {
      plotlyBackend.react(
        trend.current,
        [{ type: "scatter", mode: "lines+markers", x: cycles.map((x) => new Date(x.start * 1000)), y: durations, line: { color: c.trace }, name: "cycle" }],
        layoutOf(theme, "cycle start", "duration (s)", "date"),
        CONFIG,
      );
    }
    if (bars.current !== null) {
      const h = histogram(durations);
      plotlyBackend.react(
        bars.current,
        [{ type: "bar", x: h.centres_s, y: h.counts, width: h.width_s * 0.95, marker: { color: c.trace }, name: "cycles" }],
        layoutOf(theme, "duration (s)", "cycles", "linear"),
        CONFIG,
      );
    }
  }, [cycles, theme, near, plotly, plotlyCame]);
  useEffect(() => {
    const elements = [trend.current, bars.current];
    return () => {
      for (const el of elements) if (el !== null) plotlyBackend.purge(el);
    };
  }, []);
  return (
    <div className="plot-grid" ref={grid}>
      <div ref={trend} data-testid="cycle-trend" role="figure" aria-label="cycle durations over time" />
      <div ref={bars} data-testid="cycle-histogram" role="figure" aria-label="histogram of cycle durations" />
    </div>
  );
}

function Figure({ label, value, testId }: { readonly label: string; readonly value: string; readonly testId: string }) {
  return (
    <div className="cycle-figure">
      <span className="cycle-figure__label">{label}</span> <strong data-testid={testId}>{value}</strong>
    </div>
  );
}

function InterruptedCycles({ cycles }: { readonly cycles: readonly CycleRow[] }) {
  if (cycles.length === 0) return null;
  return (
    <div className="table-scroll" tabIndex={0} role="region" aria-label="interrupted cycles">
      <table data-testid="cycle-interrupted">
        <caption>Interrupted cycles</caption>
        <thead>
          <tr>
            <th>start</th>
            <th>duration</th>
            <th>interrupted by</th>
          </tr>
        </thead>
        <tbody>
          {cycles
            .slice(-TABLE_ROWS)
            .reverse()
            .map((c) => (
              <tr key={c.id}>
                <td className="nowrap">{formatTimestamp(c.start)}</td>
                <td>{formatCycle_s(c.duration_s)}</td>
                <td>{c.interruption ?? ""}</td>
              </tr>
            ))}
        </tbody>
      </table>
    </div>
  );
}

export const CycleView = memo(function CycleView({ robot, theme }: { readonly robot: string; readonly theme: PlotTheme }) {
  const [page, setPage] = useState<CyclePage | null>(null);
  const [error, setError] = useState<string | null>(null);
  const [include, setInclude] = useState(false);
  useEffect(() => {
    let cancelled = false;
    const load = () => {
      fetchCycles(api.client, robot, CYCLE_WINDOW, CYCLES_SHOWN, include)
        .then((answer) => {
          if (cancelled) return;
          if (answer.ok) {
            setPage(answer.page);
            setError(null);
          } else setError(answer.reason);
        })
        .catch((e: unknown) => {
          if (!cancelled) setError(String(e));
        });
    };
    load();
    const timer = window.setInterval(load, POLL_MS);
    return () => {
      cancelled = true;
      window.clearInterval(timer);
    };
  }, [robot, include]);
  // Another robot: nothing of the last one's shown meanwhile.
  useEffect(() => setPage(null), [robot]);
  const split = useMemo(() => splitCycles(page?.cycles ?? [], include), [page, include]);

  if (page === null) return <p className="hint">{error ?? "loading…"}</p>;
  if (page.trigger === null) {
    return (
      <p className="hint" data-testid="cycle-no-trigger">
        No cycle trigger is set for this robot (the setting cycle_trigger: docs/operations.md, "Cycle timing").
      </p>
    );
  }
  const s = page.statistics;
  const newest = page.cycles.slice(-TABLE_ROWS).reverse();
  const apart = interruptedWords(s);
  return (
    <div className="cycle-view" data-testid="cycle-view">
      <div className="table-view__bar">
        <span data-testid="cycle-trigger">Cycle starts on the {page.trigger.label}</span>
        <span className="table-view__source">
          {s.count} cycles measured{page.in_progress_since !== null ? `; this one since ${formatTimestamp(page.in_progress_since)}` : ""}
        </span>
        <label className="no-print">
          <input type="checkbox" data-testid="cycle-include-interrupted" checked={include} onChange={(e) => setInclude(e.target.checked)} />{" "}
          include interrupted cycles
        </label>
        <a data-testid="cycles-csv" href={cyclesCsvUrl(robot)} download>
          Export CSV
        </a>
        <button type="button" onClick={() => printSection("cycles")}>
          Print
        </button>
        {error !== null && <span className="reason">{error}</span>}
      </div>
      <h3 className="print-only">Cycle statistics of {robot}, printed {formatTimestamp(Date.now() / 1000)}</h3>
      <div className="cycle-figures">
        <Figure label="last" value={formatCycle_s(s.last_s)} testId="cycle-last" />
        <Figure label={`mean of last ${s.window || CYCLE_WINDOW}`} value={formatCycle_s(s.mean_s)} testId="cycle-mean" />
        <Figure label="min" value={formatCycle_s(s.min_s)} testId="cycle-min" />
        <Figure label="max" value={formatCycle_s(s.max_s)} testId="cycle-max" />
      </div>
      {apart !== "" && (
        <p className="hint" data-testid="cycle-interrupted-note">
          {apart}
        </p>
      )}
      <CyclePlots cycles={split.drawn} theme={theme} />
      <InterruptedCycles cycles={split.interrupted} />
      <div className="table-scroll" tabIndex={0} role="region" aria-label="newest cycles">
        <table data-testid="cycle-table">
          <thead>
            <tr>
              <th>start</th>
              <th>end</th>
              <th>duration</th>
            </tr>
          </thead>
          <tbody>
            {newest.map((c) => (
              <tr key={c.id} data-interrupted={c.interrupted ? "true" : undefined}>
                <td className="nowrap">{formatTimestamp(c.start)}</td>
                <td className="nowrap">{formatTimestamp(c.end)}</td>
                <td>
                  {formatCycle_s(c.duration_s)}
                  {c.interrupted ? ` (interrupted: ${c.interruption ?? ""})` : ""}
                </td>
              </tr>
            ))}
            {newest.length === 0 && (
              <tr>
                <td colSpan={3} className="empty">
                  no cycle measured yet
                </td>
              </tr>
            )}
          </tbody>
        </table>
      </div>
    </div>
  );
});
