import { describe, expect, it } from "vitest";
import { PlotCoordinator, type FrameScheduler } from "./plotCoordinator";
import { setupPlot as setup } from "./plotTestSupport";

describe("PlotCoordinator", () => {
  function costly(p: ReturnType<typeof setup>, clock: { now: number }, cost_ms: number) {
    const original = p.plot.update.bind(p.plot);
    p.plot.update = (t: number) => {
      clock.now += cost_ms;
      return original(t);
    };
  }

  it("updates the most overdue plot and rests per the duty cycle after an expensive update", () => {
    const clock = { now: 1000 };
    const scheduler: FrameScheduler = { now: () => clock.now, request: () => 1, cancel: () => undefined };
    const coordinator = new PlotCoordinator(scheduler);
    coordinator.maxDuty = 0.4;
    coordinator.minInterval_ms = 0;
    const plots = [setup(), setup(), setup()];
    for (const p of plots) {
      coordinator.add(p.plot);
      costly(p, clock, 10);
    }
    coordinator.tick(); // one 10 ms update, then rest 10·0.6/0.4 = 15 ms
    expect(plots.map((p) => p.plot.updates)).toEqual([1, 0, 0]);
    clock.now += 5;
    coordinator.tick(); // still resting
    expect(plots.map((p) => p.plot.updates)).toEqual([1, 0, 0]);
    clock.now += 10;
    coordinator.tick();
    coordinator.tick();
    clock.now += 15;
    coordinator.tick();
    expect(plots.map((p) => p.plot.updates)).toEqual([1, 1, 1]);
    // Plot work stays within the duty cycle: 3 × 10 ms in 10 + 5 + 10 + 10 + 15 + 10 ms.
    expect(coordinator.updateTime_ms / (clock.now - 1000)).toBeLessThanOrEqual(0.6);
  });

  it("adapts the duty to the frame rate the page reaches", () => {
    const clock = { now: 0 };
    const scheduler: FrameScheduler = { now: () => clock.now, request: () => 1, cancel: () => undefined };
    const coordinator = new PlotCoordinator(scheduler);
    const initial = coordinator.maxDuty;
    for (let i = 0; i < 300; i++) {
      clock.now += 1000 / 60; // 60 frames/s: room for more plot work
      coordinator.tick();
    }
    expect(coordinator.maxDuty).toBeGreaterThan(initial);
    expect(coordinator.maxDuty).toBeLessThanOrEqual(coordinator.maxDutyLimit);
    for (let i = 0; i < 600; i++) {
      clock.now += 1000 / 25; // 25 frames/s: below the target, back off
      coordinator.tick();
    }
    expect(coordinator.maxDuty).toBe(coordinator.minDuty);
    clock.now += 5000; // a hidden tab: no rate learnt from the pause
    coordinator.tick();
    expect(coordinator.frameInterval_ms).toBeCloseTo(40, 0);
  });

  it("fits several cheap updates into one frame's budget", () => {
    const clock = { now: 0 };
    const scheduler: FrameScheduler = { now: () => clock.now, request: () => 1, cancel: () => undefined };
    const coordinator = new PlotCoordinator(scheduler);
    coordinator.budget_ms = 8;
    coordinator.maxDuty = 1;
    const plots = [setup(), setup(), setup()];
    for (const p of plots) {
      coordinator.add(p.plot);
      costly(p, clock, 3);
    }
    coordinator.tick(); // 3 + 3 + 3 ≥ 8 stops after the third
    expect(plots.map((p) => p.plot.updates)).toEqual([1, 1, 1]);
  });

  it("does not redraw a plot more often than its minimum interval", () => {
    const clock = { now: 0 };
    const scheduler: FrameScheduler = { now: () => clock.now, request: () => 1, cancel: () => undefined };
    const coordinator = new PlotCoordinator(scheduler);
    coordinator.minInterval_ms = 50;
    const p = setup();
    coordinator.add(p.plot);
    coordinator.tick();
    expect(p.plot.updates).toBe(1);
    for (let t = 0; t < 5000; t += 10) p.push(1_000_000 + t);
    clock.now = 20;
    coordinator.tick();
    expect(p.plot.updates).toBe(1);
    clock.now = 60;
    coordinator.tick();
    expect(p.plot.updates).toBe(2);
  });

  it("refreshes plots out of view about once a second", () => {
    const clock = { now: 0 };
    const scheduler: FrameScheduler = { now: () => clock.now, request: () => 1, cancel: () => undefined };
    const coordinator = new PlotCoordinator(scheduler);
    const p = setup();
    p.plot.onScreen = false;
    coordinator.add(p.plot);
    coordinator.tick();
    expect(p.plot.updates).toBe(1);
    p.push(1000);
    p.push(2000);
    clock.now = 500;
    coordinator.tick();
    expect(p.plot.updates).toBe(1);
    clock.now = 1001;
    coordinator.tick();
    expect(p.plot.updates).toBe(2);
  });
});
