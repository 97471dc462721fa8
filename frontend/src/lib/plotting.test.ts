import { describe, expect, it } from "vitest";
import { LivePlot, PlotCoordinator, type FrameScheduler, type PlotBackend } from "./plotting";
import { ChannelMap, JOINT_PLOTS, TCP_PLOTS, axisTitle, axisTitles, tracesOf } from "./plots";
import { SampleRing } from "./ringBuffer";

type Call = { op: string; args: unknown[] };

function fakeBackend(): PlotBackend & { calls: Call[]; zoom: Record<string, unknown[]> } {
  const calls: Call[] = [];
  const zoom: Record<string, unknown[]> = {};
  const rec = (op: string) => (...args: unknown[]) => {
    calls.push({ op, args });
  };
  return {
    calls,
    zoom,
    zoomedAxes: () => zoom,
    newPlot: rec("newPlot"),
    react: rec("react"),
    extendTraces: rec("extendTraces"),
    restyle: rec("restyle"),
    relayout: rec("relayout"),
    purge: rec("purge"),
  };
}

function fakeElement(): HTMLElement {
  return { dataset: {} } as unknown as HTMLElement;
}

const spec = JOINT_PLOTS[0]!;

function setup() {
  const channels = new ChannelMap([spec]);
  const ring = new SampleRing(4096, channels.channelCount);
  const backend = fakeBackend();
  const plot = new LivePlot(spec, ring, channels, backend, { window_ms: 10_000, theme: "light", readOnly: false });
  const el = fakeElement();
  plot.mount(el);
  const push = (t_ms: number) => ring.push(t_ms, [1, 2, 3, 4, 5, 6]);
  return { ring, backend, plot, el, push };
}

describe("plot definitions", () => {
  it("name traces by the layout's channels and put the layout's units on the axes", () => {
    expect(tracesOf(spec).map((t) => t.name)).toEqual(["J 1", "J 2", "J 3", "J 4", "J 5", "J 6"]);
    expect(axisTitle(spec.series[0]!)).toBe("position [degree]");
    const velocity = TCP_PLOTS.find((p) => p.id === "plot-tcp-velocity")!;
    expect(velocity.series.map(axisTitle)).toEqual(["linear [mm/s]", "angular [degree/s]"]);
    expect(tracesOf(velocity)).toHaveLength(6);
    expect(axisTitles(spec)).toEqual({ y: "position [degree]", y2: null });
    expect(axisTitles(velocity)).toEqual({ y: "linear [mm/s]", y2: "angular [degree/s]" });
  });

  it("leaves the axis titles to the view (a Plotly axis title re-measures every tick label)", () => {
    const { backend, plot } = setup();
    plot.update(0);
    const layout = backend.calls.at(-1)!.args[2] as Record<string, { title?: unknown }>;
    expect(layout.yaxis?.title).toBeUndefined();
    expect(layout.yaxis2).toBeUndefined();
  });
});

describe("LivePlot", () => {
  it("creates the plot once, then appends with extendTraces and trims to the window", () => {
    const { backend, plot, el, push } = setup();
    expect(backend.calls.map((c) => c.op)).toEqual(["newPlot"]);
    plot.update(0); // first update: build from the (empty) ring
    expect(backend.calls.at(-1)?.op).toBe("react");
    for (let t = 0; t < 1000; t += 10) push(1_000_000 + t);
    expect(plot.update(1)).toBe(true);
    const extend = backend.calls.at(-1)!;
    expect(extend.op).toBe("extendTraces");
    const [, update, indices, maxPoints] = extend.args as [unknown, { x: unknown[][] }, number[], number];
    expect(indices).toEqual([0, 1, 2, 3, 4, 5]);
    expect(maxPoints).toBe(plot.maxPoints);
    expect(update.x).toHaveLength(6);
    expect(Number(el.dataset.points)).toBeGreaterThan(0);
    expect(backend.calls.filter((c) => c.op === "newPlot")).toHaveLength(1);
    // Nothing new: no Plotly call.
    const n = backend.calls.length;
    expect(plot.update(2)).toBe(false);
    expect(backend.calls).toHaveLength(n);
  });

  it("keeps buffering while paused and redraws the whole window on resume", () => {
    const { backend, plot, el, push, ring } = setup();
    plot.update(0);
    plot.setPaused(true);
    expect(el.dataset.paused).toBe("true");
    // Pausing redraws once, interactive, with hover.
    const paused = backend.calls.at(-1)!;
    expect(paused.op).toBe("react");
    expect((paused.args[2] as { hovermode: unknown }).hovermode).toBe("x");
    expect((paused.args[3] as { staticPlot?: boolean }).staticPlot).toBeUndefined();
    const n = backend.calls.length;
    for (let t = 0; t < 5000; t += 10) push(2_000_000 + t);
    expect(plot.hasWork()).toBe(false);
    expect(plot.update(1)).toBe(false);
    expect(backend.calls).toHaveLength(n);
    expect(ring.size).toBe(500);
    plot.setPaused(false);
    plot.update(2);
    const last = backend.calls.at(-1)!;
    expect(last.op).toBe("react");
    const data = last.args[1] as { x: number[] }[];
    expect(data[0]!.x.length).toBeGreaterThanOrEqual(290); // 5 s of a 10 s window
  });

  it("a new window rebuilds with a new uirevision; data alone keeps the zoom's uirevision", () => {
    const { backend, plot, push } = setup();
    plot.update(0);
    const rev0 = (backend.calls.at(-1)!.args[2] as { uirevision: string }).uirevision;
    push(1);
    push(5000);
    plot.update(1);
    expect(backend.calls.at(-1)!.op).toBe("extendTraces");
    plot.setWindow(30_000);
    plot.update(2);
    const rev1 = (backend.calls.at(-1)!.args[2] as { uirevision: string }).uirevision;
    expect(rev1).not.toBe(rev0);
  });

  it("rebuilds when it fell behind the ring", () => {
    const { backend, plot, push } = setup();
    plot.update(0);
    for (let t = 0; t < 5000 * 10; t += 10) push(t);
    plot.update(1);
    expect(backend.calls.at(-1)!.op).toBe("react");
  });

  it("is a static picture until the pointer is on it, interactive while it is", () => {
    const { backend, plot, el, push } = setup();
    plot.update(0);
    const config = () => backend.calls.filter((c) => c.op === "react").at(-1)!.args[3] as { staticPlot?: boolean };
    expect(config().staticPlot).toBe(true);
    push(1);
    plot.setPointerInside(true); // redraws at once
    expect(config().staticPlot).toBeUndefined();
    expect(el.dataset.interactive).toBe("true");
    plot.setPointerInside(false);
    expect(config().staticPlot).toBe(true);
    expect(el.dataset.interactive).toBe("false");
  });

  it("keeps a person's zoom when it turns static, and drops it for a new window length", () => {
    const { backend, plot } = setup();
    plot.update(0);
    plot.setPointerInside(true);
    backend.zoom.xaxis = [100, 200]; // the person zoomed while data streamed
    plot.setPointerInside(false);
    const layout = backend.calls.at(-1)!.args[2] as { xaxis: { autorange: boolean; range: number[] } };
    expect(layout.xaxis.autorange).toBe(false);
    expect(layout.xaxis.range).toEqual([100, 200]);
    plot.setWindow(30_000);
    plot.update(1);
    const fresh = backend.calls.at(-1)!.args[2] as { xaxis: { autorange: boolean; range?: number[] } };
    expect(fresh.xaxis.autorange).toBe(true);
    expect(fresh.xaxis.range).toBeUndefined();
  });

  it("signal picking restyles one trace", () => {
    const { backend, plot } = setup();
    plot.setTraceVisible(3, false);
    expect(backend.calls.at(-1)).toEqual({ op: "restyle", args: [expect.anything(), { visible: false }, [3]] });
    expect(plot.isTraceVisible(3)).toBe(false);
  });
});

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
