/**
 * Layer: the plots' animation-frame scheduler, independent of React (plain TypeScript).
 *
 * One `requestAnimationFrame` loop asks each live plot (lib/plotting.ts) to append what arrived
 * since its last update, within a time budget per animation frame and round-robin, so the page
 * keeps rendering smoothly however many plots there are; a plot scrolled out of view refreshes
 * only rarely.
 */
import type { LivePlot } from "./plotting";

/** Time source and frame scheduler of the coordinator (the browser's, or a test's). */
export interface FrameScheduler {
  now(): number;
  request(callback: () => void): number;
  cancel(handle: number): void;
}

export const browserScheduler: FrameScheduler = {
  now: () => performance.now(),
  request: (cb) => requestAnimationFrame(() => cb()),
  cancel: (h) => cancelAnimationFrame(h),
};

export class PlotCoordinator {
  private readonly plots: LivePlot[] = [];
  private readonly scheduler: FrameScheduler;
  private handle: number | null = null;
  /** Browser time before which no plot is updated (duty-cycle pacing). */
  private nextAllowed_ms = -Infinity;
  /** Work per animation frame before the remaining plots wait for the next one. */
  budget_ms = 8;
  /**
   * Share of the main thread plot updates may take. A Plotly redraw of a plot costs several
   * milliseconds; after an update of c ms the coordinator rests c·(1 − duty)/duty ms, so the page
   * keeps producing frames (and stays responsive) however slow the machine, and plots refresh as
   * often as that allows — often on a fast machine, less often on a slow one.
   */
  maxDuty = 0.4;
  /**
   * The duty adapts between these bounds to the frame rate the page actually reaches: up while
   * frames come faster than `targetFps` with a margin, down as they near it. A fast machine
   * refreshes plots more often; a slow or busy one keeps its frame rate.
   */
  minDuty = 0.2;
  maxDutyLimit = 0.7;
  targetFps = 30;
  /** Smoothed time between animation frames (ms). */
  frameInterval_ms = 1000 / 60;
  private lastTick_ms: number | null = null;
  /** A plot on screen is not redrawn more often than this (no point beyond the eye's need). */
  minInterval_ms = 50;
  /** Plots out of view are refreshed this often. */
  offscreenInterval_ms = 1000;
  ticks = 0;
  plotUpdates = 0;
  /** Time spent in plot updates (Plotly included), for the benchmark. */
  updateTime_ms = 0;
  updateTimeMax_ms = 0;

  constructor(scheduler: FrameScheduler = browserScheduler) {
    this.scheduler = scheduler;
  }

  add(plot: LivePlot): void {
    if (!this.plots.includes(plot)) this.plots.push(plot);
  }

  remove(plot: LivePlot): void {
    const i = this.plots.indexOf(plot);
    if (i >= 0) this.plots.splice(i, 1);
  }

  /** Per-plot figures, for the UI benchmark and the console. */
  stats(): { id: string; updates: number; points: number; onScreen: boolean; paused: boolean }[] {
    return this.plots.map((p) => ({
      id: p.spec.id,
      updates: p.updates,
      points: p.points,
      onScreen: p.onScreen,
      paused: p.isPaused,
    }));
  }

  start(): void {
    if (this.handle !== null) return;
    const loop = () => {
      this.handle = this.scheduler.request(loop);
      this.tick();
    };
    this.handle = this.scheduler.request(loop);
  }

  stop(): void {
    if (this.handle !== null) this.scheduler.cancel(this.handle);
    this.handle = null;
  }

  private adaptDuty(now: number): void {
    const last = this.lastTick_ms;
    this.lastTick_ms = now;
    // A gap over a second is a hidden tab or a stopped loop, not a frame rate.
    if (last === null || now - last > 1000) return;
    this.frameInterval_ms = 0.9 * this.frameInterval_ms + 0.1 * (now - last);
    if (this.ticks % 30 !== 0) return;
    const fps = 1000 / this.frameInterval_ms;
    if (fps > this.targetFps * 1.4) this.maxDuty = Math.min(this.maxDutyLimit, this.maxDuty + 0.05);
    else if (fps < this.targetFps * 1.15) this.maxDuty = Math.max(this.minDuty, this.maxDuty - 0.05);
  }

  /** The plot that waited longest among those due for an update, or null. */
  private due(now: number): LivePlot | null {
    let best: LivePlot | null = null;
    for (const plot of this.plots) {
      if (!plot.hasWork()) continue;
      const interval = plot.onScreen ? this.minInterval_ms : this.offscreenInterval_ms;
      if (now - plot.lastUpdate_ms < interval) continue;
      if (best === null || plot.lastUpdate_ms < best.lastUpdate_ms) best = plot;
    }
    return best;
  }

  /** One animation frame: update the most overdue plots until the budget is spent. */
  tick(): void {
    this.ticks++;
    const start = this.scheduler.now();
    this.adaptDuty(start);
    if (start < this.nextAllowed_ms) return;
    for (;;) {
      const now = this.scheduler.now();
      const plot = this.due(now);
      if (plot === null) return;
      if (!plot.update(now)) {
        // Nothing to draw after all (e.g. only an open bucket): do not pick it again this frame.
        plot.lastUpdate_ms = now;
        continue;
      }
      const end = this.scheduler.now();
      const spent = end - now;
      this.plotUpdates++;
      this.updateTime_ms += spent;
      if (spent > this.updateTimeMax_ms) this.updateTimeMax_ms = spent;
      this.nextAllowed_ms = end + (spent * (1 - this.maxDuty)) / this.maxDuty;
      if (end - start >= this.budget_ms || end < this.nextAllowed_ms) return;
    }
  }
}
