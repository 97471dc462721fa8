import { describe, expect, it } from "vitest";
import { PlotCoordinator, type FrameScheduler } from "./plotCoordinator";
import { setupPlot as setup } from "./plotTestSupport";

type Plot = ReturnType<typeof setup>;

/** Each update of `p` advances the fake clock by `cost_ms` (a Plotly redraw's time). */
function costly(p: Plot, clock: { now: number }, cost_ms: number) {
  const original = p.plot.update.bind(p.plot);
  p.plot.update = (t: number) => {
    clock.now += cost_ms;
    return original(t);
  };
}

function fakeScheduler(clock: { now: number }): FrameScheduler {
  return { now: () => clock.now, request: () => 1, cancel: () => undefined };
}

/**
 * A display refreshing every `vsync_ms`: each frame runs the coordinator's tick and then the
 * page's own work (`page_ms`: the stream, readouts, style, layout, paint); a frame that runs past
 * a refresh waits for the next one, as the browser's frames do. The robot's samples (every 10 ms)
 * reach each plot's ring as time goes. Returns the frames produced per second.
 */
function run(coordinator: PlotCoordinator, plots: Plot[], clock: { now: number }, seconds: number, vsync_ms = 1000 / 60, page_ms = 3) {
  const end = clock.now + seconds * 1000;
  let sampled = clock.now;
  let frames = 0;
  while (clock.now < end) {
    for (; sampled <= clock.now; sampled += 10) for (const p of plots) p.push(sampled);
    const frameStart = clock.now;
    coordinator.tick();
    clock.now += page_ms;
    frames++;
    // The next frame starts at the next refresh after this one's work.
    clock.now = frameStart + Math.max(1, Math.ceil((clock.now - frameStart) / vsync_ms)) * vsync_ms;
  }
  return frames / seconds;
}

/** From now on, the redraws of each frame the coordinator ticks, in order. */
function redrawsPerFrame(coordinator: PlotCoordinator): number[] {
  const perFrame: number[] = [];
  let before = coordinator.plotUpdates;
  const original = coordinator.tick.bind(coordinator);
  coordinator.tick = () => {
    original();
    perFrame.push(coordinator.plotUpdates - before);
    before = coordinator.plotUpdates;
  };
  return perFrame;
}

describe("PlotCoordinator", () => {
  it("redraws six plots of 9 ms each 10 times a second at over 50 frames/s on a 60 Hz display", () => {
    const clock = { now: 1000 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    coordinator.interval_ms = 100; // 60 redraws/s in all: one in every frame, no room for more
    const plots = Array.from({ length: 6 }, () => setup());
    for (const p of plots) {
      coordinator.add(p.plot);
      costly(p, clock, 9);
    }
    run(coordinator, plots, clock, 1);
    const before = plots.map((p) => p.plot.updates);
    const fps = run(coordinator, plots, clock, 20);
    // 200 redraws each in 20 s, give or take the one under way at either end.
    for (const [i, p] of plots.entries()) expect(p.plot.updates - before[i]!).toBeGreaterThanOrEqual(199);
    expect(fps).toBeGreaterThanOrEqual(55);
  });

  it("redraws six cheaper plots at their interval's rate, over 10 a second, at about 60 frames/s", () => {
    const clock = { now: 1000 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    const plots = Array.from({ length: 6 }, () => setup());
    for (const p of plots) {
      coordinator.add(p.plot);
      costly(p, clock, 5);
    }
    run(coordinator, plots, clock, 1);
    const before = plots.map((p) => p.plot.updates);
    const fps = run(coordinator, plots, clock, 20);
    const expected = (20 * 1000) / coordinator.interval_ms;
    for (const [i, p] of plots.entries()) expect(p.plot.updates - before[i]!).toBeGreaterThanOrEqual(Math.floor(expected) - 1);
    expect(expected / 20).toBeGreaterThan(10);
    expect(fps).toBeGreaterThanOrEqual(55);
  });

  it("keeps the rate when frames come late: a late redraw makes the next one sooner", () => {
    const clock = { now: 0 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    coordinator.interval_ms = 100;
    const p = setup();
    coordinator.add(p.plot);
    costly(p, clock, 2);
    run(coordinator, [p], clock, 1);
    const before = p.plot.updates;
    // 45 frames/s: a turn due every 100 ms falls between frames, late by up to 22 ms each time.
    run(coordinator, [p], clock, 20, 1000 / 45);
    expect(p.plot.updates - before).toBeGreaterThanOrEqual(199);
  });

  it("redraws a plot in view no more often than its interval, however cheap", () => {
    const clock = { now: 0 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    const plots = Array.from({ length: 3 }, () => setup());
    for (const p of plots) coordinator.add(p.plot);
    run(coordinator, plots, clock, 10);
    for (const p of plots) expect(p.plot.updates).toBeLessThanOrEqual(1 + (10 * 1000) / coordinator.interval_ms);
  });

  it("draws the beat's plots in one frame when they fit, so the page's picture changes once a beat", () => {
    const clock = { now: 0 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    const plots = Array.from({ length: 6 }, () => setup());
    for (const p of plots) {
      coordinator.add(p.plot);
      costly(p, clock, 1); // the canvas picture's cost: all six fit in a frame's budget
    }
    let beats = 0;
    coordinator.onBeat(() => beats++);
    run(coordinator, plots, clock, 2);
    const perFrame = redrawsPerFrame(coordinator);
    const beatsBefore = beats;
    const fps = run(coordinator, plots, clock, 5);
    const framesDrawing = perFrame.filter((n) => n > 0);
    const beatCount = beats - beatsBefore;
    // 5 s / 95 ms: 52 or 53 beats, each drawing all six plots in its frame.
    expect(beatCount).toBeGreaterThanOrEqual(52);
    expect(framesDrawing.length).toBe(beatCount);
    expect(framesDrawing.every((n) => n === 6)).toBe(true);
    expect(fps).toBeGreaterThanOrEqual(55);
  });

  it("draws one expensive redraw a frame after the beat, every plot still on each beat", () => {
    const clock = { now: 0 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    const plots = Array.from({ length: 4 }, () => setup());
    for (const p of plots) {
      coordinator.add(p.plot);
      costly(p, clock, 7); // Plotly's redraw: two would not fit in the budget
    }
    run(coordinator, plots, clock, 2);
    const perFrame = redrawsPerFrame(coordinator);
    const counts = plots.map((p) => p.plot.updates);
    const fps = run(coordinator, plots, clock, 5);
    expect(Math.max(...perFrame)).toBe(1);
    for (const [i, p] of plots.entries()) expect(p.plot.updates - counts[i]!).toBeGreaterThanOrEqual(52);
    expect(fps).toBeGreaterThanOrEqual(55);
  });

  it("takes a second redraw in a frame only when it fits the frame's budget", () => {
    const clock = { now: 0 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    coordinator.budget_ms = 11;
    const cheap = [setup(), setup(), setup()];
    for (const p of cheap) {
      p.push(0);
      p.push(100);
      coordinator.add(p.plot);
      costly(p, clock, 4);
    }
    coordinator.tick(); // 4 ms, then 4 + 4 ≤ 11: a second; 8 + 4 > 11: not a third
    expect(cheap.map((p) => p.plot.updates)).toEqual([1, 1, 0]);

    const clock2 = { now: 0 };
    const coordinator2 = new PlotCoordinator(fakeScheduler(clock2));
    const dear = [setup(), setup()];
    for (const p of dear) {
      p.push(0);
      p.push(100);
      coordinator2.add(p.plot);
      costly(p, clock2, 9);
    }
    coordinator2.tick(); // 9 + 9 > 11: one per frame
    expect(dear.map((p) => p.plot.updates)).toEqual([1, 0]);
  });

  it("redraws a plot out of view only every few seconds, and at once when it comes into view", () => {
    const clock = { now: 0 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    const p = setup();
    p.plot.onScreen = false;
    coordinator.add(p.plot);
    run(coordinator, [p], clock, 12);
    // Drawn at once (it has its points when it appears), then every 5 s: at 0, 5 and 10 s.
    expect(p.plot.updates).toBe(3);
    p.plot.onScreen = true;
    expect(p.plot.hasWork()).toBe(true); // 2 s of samples not drawn yet
    clock.now += 1;
    coordinator.tick();
    expect(p.plot.updates).toBe(4);
    expect(p.plot.hasWork()).toBe(false); // caught up with the ring in that one redraw
    run(coordinator, [p], clock, 2);
    expect(p.plot.updates).toBeGreaterThanOrEqual(4 + 20);
  });

  it("puts the frame rate first on a slow machine: every plot slows down alike", () => {
    const clock = { now: 0 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    const plots = Array.from({ length: 6 }, () => setup());
    for (const p of plots) {
      coordinator.add(p.plot);
      costly(p, clock, 40); // a redraw takes 40 ms here
    }
    const initial = coordinator.maxDuty;
    run(coordinator, plots, clock, 10); // the duty learns the frame rate
    const before = plots.map((p) => p.plot.updates);
    const fps = run(coordinator, plots, clock, 30);
    expect(coordinator.maxDuty).toBeLessThan(initial);
    expect(fps).toBeGreaterThanOrEqual(45);
    const counts = plots.map((p, i) => p.plot.updates - before[i]!);
    expect(Math.min(...counts)).toBeGreaterThan(0);
    expect(Math.max(...counts) - Math.min(...counts)).toBeLessThanOrEqual(1);
  });

  it("adapts the duty to the frame rate the page reaches", () => {
    const clock = { now: 0 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    const initial = coordinator.maxDuty;
    for (let i = 0; i < 300; i++) {
      clock.now += 1000 / 60; // 60 frames/s: room for more plot work
      coordinator.tick();
    }
    expect(coordinator.maxDuty).toBeGreaterThan(initial);
    expect(coordinator.maxDuty).toBeLessThanOrEqual(coordinator.maxDutyLimit);
    for (let i = 0; i < 600; i++) {
      clock.now += 1000 / 40; // 40 frames/s: below the target, back off
      coordinator.tick();
    }
    expect(coordinator.maxDuty).toBe(coordinator.minDuty);
    clock.now += 5000; // a hidden tab: no rate learnt from the pause
    coordinator.tick();
    expect(coordinator.frameInterval_ms).toBeCloseTo(25, 0);
  });

  it("keeps plot work within the duty over time", () => {
    const clock = { now: 0 };
    const coordinator = new PlotCoordinator(fakeScheduler(clock));
    coordinator.minDuty = coordinator.maxDutyLimit = coordinator.maxDuty = 0.3;
    const plots = Array.from({ length: 6 }, () => setup());
    for (const p of plots) {
      coordinator.add(p.plot);
      costly(p, clock, 12);
    }
    run(coordinator, plots, clock, 10, 1000 / 60, 0);
    // The duty plus at most one frame's budget of credit.
    expect(coordinator.updateTime_ms).toBeLessThanOrEqual(0.3 * 10_000 + coordinator.budget_ms + 12);
    expect(coordinator.updateTime_ms).toBeGreaterThan(0.25 * 10_000);
  });
});
