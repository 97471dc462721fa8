/**
 * Layer: live plots over the sample ring, independent of React (plain TypeScript).
 *
 * `LivePlot` is one plot's state (docs/architecture.md "Plots: from the ring into the
 * recording"): its view — "ring" (a window of up to 2 min from the ring alone), "moving" (a long
 * window from the recording, moving with now) or "fixed" (a range of the past) — and the moves
 * between views (a person's zoom or pan, a step, the wheel, a jump, back to live, and the same
 * moves followed from another plot of the panel's one time axis), pause, visibility,
 * interactivity, and `update()` for the coordinator's animation-frame turns (lib/plots/plotCoordinator.ts).
 * Each view's own side is a module of its own: the ring's reading (lib/plots/plotRingView.ts, its
 * start from the recording lib/plots/plotBackfill.ts), the moving window's policy
 * (lib/plots/plotMovingView.ts), a fixed range's decisions (lib/plots/plotFixedView.ts), the recording's
 * fetching and traces (lib/plots/plotRecordingView.ts); how it looks is lib/plots/plotAppearance.ts. A static
 * live plot is drawn by its `StaticPicture` (plots/canvasPlot.ts), else by Plotly through
 * `PlotBackend` (lib/plots/plotlyAdapter.ts). Must not import Plotly or React.
 */
import type { TimeRange } from "./historyView";
import { LivePlotDrawing } from "./livePlotDrawing";
import { unrecordedStart } from "./plotExport";
import { axisSpan_ms, reachesRecording, sameSpan, showsRange } from "./plotFixedView";
import type { PlotView } from "./plotRecordingView";
import { stepRange, zoomAround, type PlotStep, type SpanMs } from "./plotSteps";
import type { PlotMove } from "./timeRange";

export type { PlotBackend, StaticPicture } from "./plotBackend";
export type { LivePlotOptions } from "./livePlotDrawing";

export class LivePlot extends LivePlotDrawing {
  /**
   * Draw into `el` from the next update on. Plotly's plot is made at once only for a plot
   * without a picture (and Plotly there); otherwise the first time Plotly draws it.
   */
  mount(el: HTMLElement): void {
    this.el = el;
    if (this.picture === null && this.plotlyReady()) this.plotlyIn(el);
    this.needsRebuild = true;
  }

  protected personRelayout(): void {
    this.checkZoom();
  }

  private checkZoom(): void {
    if (this.el === null) return;
    const axes = this.backend.zoomedAxes(this.el);
    if (this.recording !== null) this.followPerson(axes.xaxis);
    if (this.el === null) return;
    const keys = Object.keys(axes);
    // A history view sets its x range itself: only the person's y zoom counts there.
    const zoomed =
      this.view.kind === "fixed" ||
      (this.view.kind === "ring" ? keys.length > 0 : keys.some((k) => k !== "xaxis"));
    this.setZoomed(zoomed);
  }

  /**
   * A person zoomed or panned to `x` (Plotly's x range, or undefined after an autoscale). On
   * the ring, a view inside what the plot holds stays a zoom of the moving window (no fetch);
   * one reaching before it goes into the recording. A history view follows every move with a
   * debounced fetch of the new range; an autoscale there is "Back to live".
   */
  private followPerson(x: readonly unknown[] | undefined): void {
    if (x === undefined) {
      if (this.view.kind === "fixed") this.backToLive();
      return;
    }
    const range = axisSpan_ms(x, this.tzShift_ms);
    if (range === null) return;
    // Our own drawing of a range is no move of the person's.
    if (this.view.kind !== "ring" && sameSpan(range, this.drawnRange_ms)) return;
    // Plotly shows the person's range already: nothing to draw before its answer.
    this.goTo(range, false);
  }

  /**
   * The one decision for a new time range, a person's (Plotly shows it already) or a step's
   * (`draw`: put Plotly on it here). A history view follows with a debounced fetch; on the ring,
   * a range inside what the plot holds stays a zoom of the moving window (no fetch), one reaching
   * before it goes into the recording. Without a recording (the loader) only the ring zoom.
   */
  private goTo(range: SpanMs, draw: boolean): void {
    this.told({ kind: "range", range: { from_s: range.from / 1000, to_s: range.to / 1000 } });
    if (this.recording !== null && reachesRecording(this.view.kind, this.ringView.heldFrom_ms(), range)) {
      this.enterView({ kind: "fixed", from_ms: range.from, to_ms: range.to }, { immediate: false, redraw: draw, fresh: false });
      return;
    }
    if (draw) this.zoomRing(range);
  }

  /** Tell the panel's time axis of a person's move on this plot (not of one it follows). */
  private told(move: PlotMove): void {
    if (!this.following) this.onMove?.(move);
  }

  /**
   * Follow a move a person made on another plot of the panel: the same decision as that move
   * on this plot (a range is a zoom of the ring or a range of the recording), not told on.
   */
  follow(move: PlotMove): void {
    if (this.el === null || this.options.readOnly) return;
    this.following = true;
    try {
      if (move.kind === "range") {
        const range = { from: move.range.from_s * 1000, to: move.range.to_s * 1000 };
        // Already there (a move's echo): nothing to draw.
        if (!sameSpan(range, this.shownRange_ms())) this.goTo(range, true);
      } else if (move.kind === "window") this.setWindow(move.window_ms);
      else if (move.kind === "jump") this.showRange(move.range);
      else if (this.paused || this.zoomed || this.view.kind === "fixed") this.backToLive();
    } finally {
      this.following = false;
    }
  }

  /** Show `range` as a zoom of the ring view (a step's, as a person's Plotly zoom would). */
  private zoomRing(range: SpanMs): void {
    const el = this.el;
    if (el === null) return;
    const x = [range.from - this.tzShift_ms, range.to - this.tzShift_ms];
    if (this.paused && this.onPicture) {
      // Paused before Plotly came: the frozen picture, zoomed (no data added).
      this.pictureZoom = { ...this.pictureZoom, xaxis: x };
      this.drawPicture();
    } else if (this.paused) {
      // Paused: the frozen picture stays (Plotly's relayout, as a person's zoom; no data added).
      this.plotlyIn(el).relayout(el, { "xaxis.autorange": false, "xaxis.range": x });
    } else {
      this.stepZoom = x;
      this.rebuild(el);
    }
    this.setZoomed(true);
  }

  /**
   * A step of the time axis from a button or a key (lib/plots/plotSteps.ts): zoom in or out around
   * the centre, pan earlier or later by half the range in view. The new range takes the same
   * decision as a person's zoom or pan (`goTo`); "Later" onto now is back to live. A plot
   * without the recording stays within what its ring view holds.
   */
  step(step: PlotStep): void {
    if (this.el === null || this.options.readOnly) return;
    const shown = this.shownRange_ms();
    if (shown === null) return;
    // Without the recording, nothing is newer than the ring's newest frame.
    const now = this.recording === null ? (this.ring.newestTime() ?? this.now_ms()) : this.now_ms();
    this.moveTo(stepRange(shown, step, now), now);
  }

  /**
   * Zoom the time axis by `factor` around `at_ms` (the mouse wheel: the time under the pointer
   * stays), never past now; the same decision as a step.
   */
  zoomAt(at_ms: number, factor: number): void {
    if (this.el === null || this.options.readOnly) return;
    const shown = this.shownRange_ms();
    if (shown === null) return;
    const now = this.recording === null ? (this.ring.newestTime() ?? this.now_ms()) : this.now_ms();
    this.moveTo(zoomAround(shown, at_ms, factor, now), now);
  }

  private moveTo(range: SpanMs | "live" | null, now: number): void {
    let next = range;
    if (next !== null && next !== "live" && this.recording === null) next = this.ringView.within(next, now);
    if (next === null) return;
    if (next !== "live") this.goTo(next, true);
    // Already live: nothing to redraw.
    else if (this.paused || this.zoomed || this.view.kind === "fixed") this.backToLive();
  }

  /** The time range in view now (ms since the epoch), the cursor's frame of reference. */
  shownRange(): SpanMs | null {
    return this.shownRange_ms();
  }

  /** The range in view (ms since the epoch): a fixed view's own (even before it is drawn). */
  private shownRange_ms(): SpanMs | null {
    if (this.view.kind === "fixed") return { from: this.view.from_ms, to: this.view.to_ms };
    const r = this.visibleRange();
    return r === null ? null : { from: r.from_s * 1000, to: r.to_s * 1000 };
  }

  /**
   * Show a fixed range of the past (a marker's jump, a custom range), fetched at once; the
   * plot leaves a pause (it shows what was asked for).
   */
  showRange(range: TimeRange): void {
    if (this.recording === null || !(range.to_s > range.from_s)) return;
    this.told({ kind: "jump", range });
    this.paused = false;
    this.enterView({ kind: "fixed", from_ms: range.from_s * 1000, to_ms: range.to_s * 1000 }, { immediate: true, redraw: true, fresh: true });
  }

  /** Whether the plot shows `range` (a fixed range of the past, to the millisecond). */
  isShowing(range: TimeRange): boolean {
    return showsRange(this.view, range);
  }

  /**
   * Switch views. `immediate`: fetch now, not after the debounce; `redraw`: draw the new range at
   * once (with what is at hand) rather than when its answer comes (a person's move has put
   * Plotly on the range already); `fresh`: a new `uirevision`, dropping the person's zoom.
   */
  private enterView(view: PlotView, how: { immediate: boolean; redraw: boolean; fresh: boolean }): void {
    this.clearRefresh();
    this.view = view;
    if (how.fresh) this.revision++;
    if (view.kind === "ring") {
      this.recording?.stopRequests();
      this.revisions.reset();
      this.historyData = null;
      this.historyError = null;
      this.drawnRange_ms = null;
      this.needsRebuild = true;
    } else {
      this.requestRange(how.immediate);
      if (how.redraw) this.needsRebuild = true;
    }
    this.setZoomed(view.kind === "fixed");
    this.mark();
    this.tell();
  }

  /** The range in view now (s since the epoch): what an export of "the view" covers. */
  visibleRange(): TimeRange | null {
    if (this.view.kind !== "ring") {
      const r = this.drawnRange_ms ?? this.wantedRange_ms();
      return { from_s: r.from / 1000, to_s: r.to / 1000 };
    }
    const zoom = axisSpan_ms(this.currentZoom().xaxis, this.tzShift_ms);
    if (zoom !== null) return { from_s: zoom.from / 1000, to_s: zoom.to / 1000 };
    // Paused: the range of the picture as it froze, not up to the ring's newest.
    const frozen = this.paused ? this.ringView.drawnRange() : null;
    if (frozen !== null) return { from_s: frozen.from / 1000, to_s: frozen.to / 1000 };
    const to = this.ring.newestTime() ?? this.clock();
    // While the recording fills the window's front (lib/plots/plotBackfill.ts) the axis shows the whole
    // window: so does the export, not only what reached the page since it opened (issue 38).
    const from = this.backfill?.drawnFrom_ms(this.window_ms) ?? this.ringView.start_ms(to);
    return { from_s: from / 1000, to_s: to / 1000 };
  }

  /**
   * The start of the view the recording has nothing of (s since the epoch), or null: said on the
   * plot and by its export ("nothing recorded from … to …", lib/plots/plotExport.ts).
   */
  unrecorded(): TimeRange | null {
    if (this.view.kind === "ring") return this.backfill?.unrecorded() ?? null;
    const data = this.historyData;
    return data === null ? null : unrecordedStart(data.range, data.answer);
  }

  /**
   * Back to the moving window: unpaused, every axis autoranged again (a zoom is dropped with a
   * new `uirevision`), the whole window redrawn from the ring at once.
   */
  backToLive(): void {
    this.told({ kind: "live" });
    this.paused = false;
    // The picked window again: from the ring, or a long one from the recording (asked at once).
    this.enterView(this.viewForWindow(this.window_ms), { immediate: true, redraw: true, fresh: true });
    this.setZoomed(false);
    if (this.el !== null) this.rebuild(this.el);
    this.mark();
  }

  /** A window picked: on the ring up to 2 min, longer ones from the recording (moving with now). */
  setWindow(window_ms: number): void {
    if (window_ms === this.window_ms && this.view.kind !== "fixed") return;
    this.told({ kind: "window", window_ms });
    this.window_ms = window_ms;
    this.onWindowChange?.(window_ms);
    this.ringView.setWindow(window_ms);
    // A new window length starts from autorange, not the old zoom (a new revision).
    this.enterView(this.viewForWindow(window_ms), { immediate: true, redraw: true, fresh: true });
  }

  setPaused(paused: boolean): void {
    if (paused === this.paused) return;
    if (!paused) {
      // Resuming is going back to live: the moving window, not a zoom into a time now past
      // (with it the plot would scroll out of the range and go blank).
      this.backToLive();
      return;
    }
    this.paused = true;
    // Pausing redraws once, interactive with hover (see `interactive`), frozen from then on.
    if (this.el !== null) this.rebuild(this.el);
    this.mark();
  }

  /**
   * The pointer entered or left the plot. A live plot is a static picture (no zoom layer, no
   * hover) while nobody points at it — a Plotly redraw costs markedly less so — and becomes
   * interactive as soon as the pointer is on it, so a person can zoom while data streams;
   * `uirevision` keeps that zoom when it turns static again.
   */
  setPointerInside(inside: boolean): void {
    if (inside === this.pointerInside) return;
    const before = this.interactive;
    this.pointerInside = inside;
    this.interactiveChanged(before);
  }

  /** The keyboard's focus entered or left the plotting area: interactive as with the pointer. */
  setFocusInside(inside: boolean): void {
    if (inside === this.focusInside) return;
    const before = this.interactive;
    this.focusInside = inside;
    this.interactiveChanged(before);
  }

  private interactiveChanged(before: boolean): void {
    // At once, not at the next tick: the person may start dragging a zoom box right away.
    if (this.interactive !== before && !this.paused && this.el !== null) this.rebuild(this.el);
  }
}
