import { describe, expect, it } from "vitest";
import { TCP_PLOTS, axisTitle, axisTitles, tracesOf } from "./plots";
import { fakeBackend, fakeElement, recordingPicture, setupPlot as setup, spec } from "./plotTestSupport";
import { LivePlot } from "./plotting";
import { ChannelMap } from "./plots";
import { SampleRing } from "../stream/ringBuffer";
import { BUCKETS_PER_WINDOW } from "./plotAppearance";

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
    expect(data[0]!.x.length).toBeGreaterThanOrEqual(BUCKETS_PER_WINDOW - 10); // 5 s of a 10 s window, 2 points a bucket
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

describe("the kiosk's plot (read-only)", () => {
  it("is drawn by its picture on every update: Plotly is never called", () => {
    const channels = new ChannelMap([spec]);
    const ring = new SampleRing(4096, channels.channelCount);
    const backend = fakeBackend();
    const { picture, drawn } = recordingPicture();
    const plot = new LivePlot(spec, ring, channels, backend, { window_ms: 10_000, theme: "dark", readOnly: true, staticPicture: picture });
    const el = fakeElement();
    plot.mount(el);
    plot.update(0);
    for (let t = 0; t < 1000; t += 10) ring.push(1_000_000 + t, [1, 2, 3, 4, 5, 6]);
    expect(plot.update(1)).toBe(true);
    plot.setPointerInside(true); // no pointer counts on the kiosk: it stays a picture
    ring.push(1_001_000, [1, 2, 3, 4, 5, 6]);
    expect(plot.update(2)).toBe(true);
    expect(backend.calls.map((c) => c.op)).toEqual([]);
    expect(drawn).toEqual(["reset", "show", "draw", "extend", "draw", "extend", "draw"]);
    expect(el.dataset.renderer).toBe("canvas");
  });
});
