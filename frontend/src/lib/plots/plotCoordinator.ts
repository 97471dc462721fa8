/**
 * Layer: the plots' animation-frame scheduler, independent of React (plain TypeScript).
 *
 * One `requestAnimationFrame` loop asks each live plot (lib/plots/plotting.ts) to append what arrived
 * since its last update, on one beat for the page: every `interval_ms` (10 times a second, the
 * monitoring values' own rate, on a grid of the page's clock) the plots in view are drawn in the
 * same animation frame, and the readouts that follow the stream (`onBeat`) are written in it too.
 * Each picture the page changes costs a commit to the compositor (its layers updated, every
 * canvas handed over, paint), whatever it changed: one frame changed ten times a second costs a
 * sixth of six frames changed one after another. A frame takes further redraws only while they
 * fit the frame's budget (an expensive Plotly redraw waits for the next frame, and draws on the
 * next beat again). A late redraw keeps the plot's rate: its next turn is the next beat. A plot out
 * of view is redrawn only every few seconds (so it is never far behind, and what reads its data
 * attributes sees it move), and at once when it comes into view; a history view draws an answer
 * when it comes. On a slow or busy machine the frame rate comes first: the share of the main
 * thread the plots may take adapts to the frame rate the page reaches, and all plots slow down
 * alike.
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
  /** When each plot is due next (browser time, ms). */
  private readonly dueAt = new Map<LivePlot, number>();
  /** When each plot was last drawn (browser time, ms). */
  private readonly drawnAt = new Map<LivePlot, number>();
  /** The plots tried in the current frame (kept, not allocated per frame). */
  private readonly tried = new Set<LivePlot>();
  private readonly scheduler: FrameScheduler;
  private handle: number | null = null;
  /** Told on every beat, in the frame the plots are drawn in (the numeric readouts). */
  private readonly beatListeners = new Set<() => void>();
  /** When the next beat is due (browser time, ms; on the grid of `interval_ms`). */
  private beatAt_ms = -Infinity;
  /**
   * Plot work the duty allows now (ms): earned at `maxDuty` ms per ms of time, at most one
   * frame's budget, spent by each update; no update while it is not positive.
   */
  private credit_ms = 0;
  private creditSince_ms: number | null = null;
  /**
   * The beat: each plot in view is redrawn this often: the monitoring values refresh every
   * 100 ms, and a little more often than that keeps a plot at 10 redraws/s or more when a frame
   * now and then comes too late for anything (each redraw still brings new samples: they come
   * every 10 ms).
   */
  interval_ms = 95;
  /** A plot out of view is redrawn this often (it catches up at once when it comes into view). */
  offscreenInterval_ms = 5000;
  /**
   * Plot work per animation frame: a further redraw in the same frame only when what was spent
   * and the expected cost of another fit in it. A frame at 60 frames/s is 16.7 ms and the page
   * has work of its own in it, more in a beat's frame (the stream, the readouts, a React render,
   * style, layout, paint and the commit). The canvas picture draws a plot in about a
   * millisecond: all six of the panel's in one frame; Plotly's redraw (7 ms or more) one a
   * frame, over the frames after the beat.
   */
  budget_ms = 10;
  /** Smoothed cost of one redraw (ms), to judge whether another fits in the frame. */
  updateCost_ms = 0;
  /**
   * Share of the main thread plot updates may take over time (a credit earned at this rate,
   * spent by each update), so the page keeps producing frames and stays responsive however slow
   * the machine or expensive a redraw.
   */
  maxDuty = 0.5;
  /**
   * The duty adapts between these bounds to the frame rate the page actually reaches: up while
   * frames come faster than `targetFps` with a margin, down when they come slower. A fast machine
   * refreshes plots as often as they are due; a slow or busy one keeps its frame rate.
   */
  minDuty = 0.15;
  maxDutyLimit = 0.75;
  targetFps = 50;
  /** Smoothed time between animation frames (ms). */
  frameInterval_ms = 1000 / 60;
  private lastTick_ms: number | null = null;
  ticks = 0;
  plotUpdates = 0;
  /** Time spent in plot updates (Plotly included), for the benchmark. */
  updateTime_ms = 0;
  updateTimeMax_ms = 0;

  constructor(scheduler: FrameScheduler = browserScheduler) {
    this.scheduler = scheduler;
  }

  add(plot: LivePlot): void {
    if (this.plots.includes(plot)) return;
    this.plots.push(plot);
    this.dueAt.set(plot, -Infinity);
    this.drawnAt.set(plot, -Infinity);
  }

  remove(plot: LivePlot): void {
    const i = this.plots.indexOf(plot);
    if (i >= 0) this.plots.splice(i, 1);
    this.dueAt.delete(plot);
    this.drawnAt.delete(plot);
  }

  /**
   * Call `listener` on every beat, in the animation frame the plots are drawn in, so that what
   * it changes on the page is committed with them; returns its removal.
   */
  onBeat(listener: () => void): () => void {
    this.beatListeners.add(listener);
    return () => {
      this.beatListeners.delete(listener);
    };
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
    if (fps >= this.targetFps * 1.1) this.maxDuty = Math.min(this.maxDutyLimit, this.maxDuty + 0.05);
    else if (fps < this.targetFps) this.maxDuty = Math.max(this.minDuty, this.maxDuty - 0.05);
  }

  /**
   * When the plot's turn comes: its own schedule in view (or for a history view's answer); out
   * of view, the first beat a while after its last drawing.
   */
  private turnOf(plot: LivePlot): number {
    if (plot.onScreen || plot.viewKind !== "ring") return this.dueAt.get(plot) ?? -Infinity;
    const drawn = this.drawnAt.get(plot) ?? -Infinity;
    return Number.isFinite(drawn) ? this.nextBeat(drawn + this.offscreenInterval_ms) : -Infinity;
  }

  /**
   * The due plot whose turn came first (not yet tried in this frame), or null.
   */
  private due(now: number, tried: ReadonlySet<LivePlot>): LivePlot | null {
    let best: LivePlot | null = null;
    let bestDue = Infinity;
    for (const plot of this.plots) {
      if (tried.has(plot) || !plot.hasWork()) continue;
      const due = this.turnOf(plot);
      if (due > now) continue;
      if (best === null || due < bestDue) {
        best = plot;
        bestDue = due;
      }
    }
    return best;
  }

  /** The first beat after `now` (browser time, ms): the grid of `interval_ms` every plot shares. */
  private nextBeat(now: number): number {
    return (Math.floor(now / this.interval_ms) + 1) * this.interval_ms;
  }

  /**
   * The plot's next turn: the beat after the one it was drawn for, with every other plot in view.
   * A redraw that came late (its frame came late, or the budget put it off a frame or more)
   * keeps the rate: the next turn is still the beat after its own, at once when that beat has
   * come meanwhile; one turn at once at most (after a pause, a slow stretch, out of view), no
   * burst to make up for all that was missed. A first drawing's turn is the next beat.
   */
  private schedule(plot: LivePlot, now: number): void {
    const due = this.dueAt.get(plot) ?? -Infinity;
    const lastBeat = Math.floor(now / this.interval_ms) * this.interval_ms;
    this.dueAt.set(plot, Number.isFinite(due) ? Math.max(this.nextBeat(due), lastBeat) : this.nextBeat(now));
  }

  /** The beat's listeners, once per beat, in the frame the beat's plots are drawn in. */
  private beat(now: number): void {
    if (now < this.beatAt_ms) return;
    this.beatAt_ms = this.nextBeat(now);
    for (const listener of this.beatListeners) listener();
  }

  /**
   * One animation frame: the beat's listeners when a beat came, and the due plots, earliest turn
   * first, within the frame's budget and the duty.
   */
  tick(): void {
    this.ticks++;
    const start = this.scheduler.now();
    this.adaptDuty(start);
    this.beat(start);
    // Plot work earns credit at the duty's rate; an update spends what it cost.
    this.credit_ms =
      this.creditSince_ms === null
        ? this.budget_ms
        : Math.min(this.budget_ms, this.credit_ms + Math.max(0, start - this.creditSince_ms) * this.maxDuty);
    this.creditSince_ms = start;
    const tried = this.tried;
    tried.clear();
    let updated = 0;
    while (this.credit_ms > 0) {
      const now = this.scheduler.now();
      // A further redraw in this frame only when it fits: the beat's plots share a frame (and
      // one commit of the page's picture) as far as the budget allows.
      if (updated > 0 && now - start + this.updateCost_ms > this.budget_ms) return;
      const plot = this.due(now, tried);
      if (plot === null) return;
      tried.add(plot);
      if (!plot.update(now)) {
        // Nothing to draw after all (e.g. only an open bucket): tried again next frame.
        continue;
      }
      const spent = this.scheduler.now() - now;
      updated++;
      this.schedule(plot, now);
      this.drawnAt.set(plot, now);
      this.credit_ms -= spent;
      this.plotUpdates++;
      this.updateTime_ms += spent;
      if (spent > this.updateTimeMax_ms) this.updateTimeMax_ms = spent;
      this.updateCost_ms = this.updateCost_ms === 0 ? spent : 0.9 * this.updateCost_ms + 0.1 * spent;
    }
  }
}
