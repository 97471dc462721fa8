// Back to live after a zoom, hover with units while live, PNG export (lib/plots/plotting.ts).
import { describe, expect, it } from "vitest";
import { BUCKETS_PER_WINDOW } from "./plotAppearance";
import { LivePlot } from "./plotting";
import { ChannelMap, JOINT_PLOTS } from "./plots";
import { SampleRing } from "../stream/ringBuffer";
import { fakeBackend } from "./plotTestSupport";

type Layout = { uirevision: string; hovermode: unknown; xaxis: { autorange: boolean; range?: unknown[] }; yaxis: { autorange: boolean; range?: unknown[] } };

function setup() {
  const backend = fakeBackend();
  const { calls, zoom } = backend;
  const spec = JOINT_PLOTS[0]!;
  const channels = new ChannelMap([spec]);
  const ring = new SampleRing(4096, channels.channelCount);
  const plot = new LivePlot(spec, ring, channels, backend, { window_ms: 10_000, theme: "light", readOnly: false });
  const el = { dataset: {}, clientWidth: 600, clientHeight: 240 } as unknown as HTMLElement;
  plot.mount(el);
  const zoomed: boolean[] = [];
  plot.onZoomedChange = (z) => zoomed.push(z);
  const push = (t_ms: number) => ring.push(t_ms, [1, 2, 3, 4, 5, 6]);
  /** A person zooms the x axis into [from, to] (Plotly then tells its relayout listeners). */
  const zoomTo = (from: number, to: number) => {
    zoom.xaxis = [from, to];
    backend.fireRelayout();
  };
  const unzoomInPlotly = () => {
    delete zoom.xaxis;
  };
  const lastReact = () => calls.filter((c) => c.op === "react").at(-1)!;
  return { calls, plot, el, push, zoomTo, unzoomInPlotly, zoomed, lastReact };
}

describe("back to live", () => {
  it("knows when a person zoomed away from the moving window", () => {
    const { plot, el, zoomTo, zoomed } = setup();
    plot.update(0);
    expect(plot.isZoomed).toBe(false);
    zoomTo(100, 200);
    expect(plot.isZoomed).toBe(true);
    expect(el.dataset.zoomed).toBe("true");
    expect(zoomed).toEqual([true]);
  });

  it("restores the moving window after a zoom: autorange, a new uirevision, the whole window", () => {
    const { plot, push, zoomTo, unzoomInPlotly, zoomed, lastReact, el } = setup();
    for (let t = 0; t < 8000; t += 10) push(1_000_000 + t);
    plot.update(0);
    const before = lastReact().args[2] as Layout;
    plot.setPointerInside(true);
    zoomTo(1_000_100, 1_000_200);
    plot.setPointerInside(false); // a redraw within the same revision keeps the zoom
    expect((lastReact().args[2] as Layout).xaxis.range).toEqual([1_000_100, 1_000_200]);
    plot.backToLive();
    unzoomInPlotly(); // what Plotly.react with a new uirevision does
    const live = lastReact().args[2] as Layout;
    expect(live.xaxis.autorange).toBe(true);
    expect(live.xaxis.range).toBeUndefined();
    expect(live.uirevision).not.toBe(before.uirevision);
    const data = lastReact().args[1] as { x: number[] }[];
    expect(data[0]!.x.length).toBeGreaterThan(1.5 * BUCKETS_PER_WINDOW); // 8 s of the 10 s window, at once
    expect(plot.isZoomed).toBe(false);
    expect(el.dataset.zoomed).toBe("false");
    expect(zoomed).toEqual([true, false]);
    // And it keeps moving: new data is appended, not redrawn into the old range.
    push(1_008_000);
    push(1_009_000);
    expect(plot.update(1)).toBe(true);
  });

  it("resuming after a pause and a zoom goes back to live (the plot no longer goes blank)", () => {
    const { plot, push, zoomTo, lastReact } = setup();
    push(1_000_000);
    plot.update(0);
    plot.setPaused(true);
    const paused = lastReact().args[2] as Layout;
    zoomTo(1_000_000, 1_000_050);
    for (let t = 0; t < 20_000; t += 10) push(1_000_010 + t); // the ring moves on meanwhile
    plot.setPaused(false);
    const resumed = lastReact().args[2] as Layout;
    expect(plot.isPaused).toBe(false);
    expect(resumed.xaxis.autorange).toBe(true);
    expect(resumed.xaxis.range).toBeUndefined();
    expect(resumed.uirevision).not.toBe(paused.uirevision);
    const xs = (lastReact().args[1] as { x: number[] }[])[0]!.x;
    // The newest 10 s, not the zoomed 50 ms of the past.
    const tz = new Date().getTimezoneOffset() * 60_000;
    expect(Math.max(...xs)).toBeGreaterThan(1_019_000 - tz);
    expect(Math.min(...xs)).toBeGreaterThanOrEqual(1_010_000 - tz - 100);
  });
});

describe("hover while live", () => {
  it("shows the value with the layout's unit as soon as the pointer is on the plot", () => {
    const { plot, push, lastReact } = setup();
    push(1);
    plot.update(0);
    expect((lastReact().args[2] as Layout).hovermode).toBe(false); // static picture
    plot.setPointerInside(true);
    expect(plot.isPaused).toBe(false);
    expect((lastReact().args[2] as Layout).hovermode).toBe("x");
    const traces = lastReact().args[1] as { hovertemplate: string; hoverinfo?: string }[];
    expect(traces[0]!.hovertemplate).toContain("J 1: %{y");
    expect(traces[0]!.hovertemplate).toContain(" degree");
    expect(traces[0]!.hoverinfo).toBeUndefined();
  });
});

describe("PNG export", () => {
  it("saves the plot under the name given", () => {
    const { plot, calls } = setup();
    plot.exportPng("plot-joint-position-2026");
    const call = calls.at(-1)!;
    expect(call.op).toBe("downloadPng");
    expect(call.args[1]).toBe("plot-joint-position-2026");
  });
});
