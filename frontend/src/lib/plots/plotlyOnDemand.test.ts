import { describe, expect, it, vi } from "vitest";
import { fakeBackend, fakeElement, recordingPicture, spec } from "./plotTestSupport";
import { LivePlot } from "./plotting";
import { ChannelMap } from "./plots";
import { SampleRing } from "../stream/ringBuffer";

/** A recording backend whose Plotly comes only when the test says so (or fails to). */
function lateBackend() {
  const backend = fakeBackend();
  let here = false;
  let loads = 0;
  let settle: { come: () => void; fail: () => void } | null = null;
  const late = Object.assign(backend, {
    ready: () => here,
    load: () => {
      loads++;
      return new Promise<void>((resolve, reject) => {
        settle = {
          come: () => {
            here = true;
            resolve();
          },
          fail: () => reject(new Error("chunk not served")),
        };
      });
    },
  });
  return {
    backend: late,
    loads: () => loads,
    /** Plotly comes (or fails); the plot is told in a microtask, as after a real import. */
    come: async () => {
      settle?.come();
      await Promise.resolve();
    },
    fail: async () => {
      settle?.fail();
      await Promise.resolve();
      await Promise.resolve();
    },
  };
}

function panelPlot(withPicture = true) {
  const channels = new ChannelMap([spec]);
  const ring = new SampleRing(4096, channels.channelCount);
  const late = lateBackend();
  const { picture, drawn } = recordingPicture([1_000_000, 1_000_990]);
  const plot = new LivePlot(spec, ring, channels, late.backend, {
    window_ms: 10_000,
    theme: "light",
    readOnly: false,
    ...(withPicture ? { staticPicture: picture } : {}),
  });
  const el = fakeElement();
  plot.mount(el);
  for (let t = 0; t < 1000; t += 10) ring.push(1_000_000 + t, [1, 2, 3, 4, 5, 6]);
  const ops = () => late.backend.calls.map((c) => c.op);
  return { plot, el, ring, drawn, ops, ...late };
}

describe("Plotly on demand", () => {
  it("a plot nobody points at never asks for Plotly; pointed at, it asks once and turns into Plotly's plot when it comes", async () => {
    const { plot, el, ops, loads, come } = panelPlot();
    plot.update(0);
    expect(ops()).toEqual([]);
    expect(loads()).toBe(0);
    expect(el.dataset.renderer).toBe("canvas");

    plot.setPointerInside(true);
    plot.update(1);
    plot.setFocusInside(true);
    expect(loads()).toBe(1); // asked once, however often it is wanted meanwhile
    expect(ops()).toEqual([]);
    expect(el.dataset.renderer).toBe("canvas"); // the picture until it comes

    await come();
    expect(ops()).toEqual(["newPlot", "react"]); // at once, not at the next beat
    expect(el.dataset.renderer).toBe("plotly");
    plot.setFocusInside(false);
    plot.setPointerInside(false);
    expect(el.dataset.renderer).toBe("canvas");
  });

  it("Plotly that comes after the pointer left draws nothing", async () => {
    const { plot, el, ops, come } = panelPlot();
    plot.update(0);
    plot.setPointerInside(true);
    plot.setPointerInside(false);
    await come();
    plot.update(1);
    expect(ops()).toEqual([]);
    expect(el.dataset.renderer).toBe("canvas");
  });

  it("a failed load is asked again at the next need", async () => {
    const warn = vi.spyOn(console, "warn").mockImplementation(() => undefined);
    const { plot, loads, fail, come, el } = panelPlot();
    plot.update(0);
    plot.setPointerInside(true);
    await fail();
    expect(el.dataset.renderer).toBe("canvas");
    plot.setPointerInside(false);
    plot.setPointerInside(true);
    expect(loads()).toBe(2);
    await come();
    expect(el.dataset.renderer).toBe("plotly");
    expect(warn).toHaveBeenCalledOnce(); // the failure is said
    warn.mockRestore();
  });

  it("paused before Plotly came, it shows the range that froze when it comes", async () => {
    const { plot, ring, backend, come } = panelPlot();
    plot.update(0);
    plot.setPaused(true);
    const frozen = plot.visibleRange();
    for (let t = 1000; t < 3000; t += 10) ring.push(1_000_000 + t, [1, 2, 3, 4, 5, 6]);
    await come();
    const react = backend.calls.find((c) => c.op === "react");
    const x = (react?.args[2] as { xaxis: { range: number[] } }).xaxis.range;
    const shift = new Date().getTimezoneOffset() * 60_000;
    expect(frozen).not.toBeNull();
    expect(x[0]! + shift).toBeCloseTo(frozen!.from_s * 1000, 3);
    expect(x[1]! + shift).toBeCloseTo(frozen!.to_s * 1000, 3);
  });

  it("a plot without a picture (?plotPicture=off) asks at once and is drawn whole when Plotly comes", async () => {
    const { plot, el, ops, loads, come } = panelPlot(false);
    plot.update(0);
    expect(ops()).toEqual([]);
    expect(loads()).toBe(1);
    expect(plot.hasWork()).toBe(true); // its rebuild waits
    await come();
    plot.update(1);
    expect(ops()).toEqual(["newPlot", "react"]);
    expect(el.dataset.renderer).toBeUndefined(); // no picture to hide
  });

  it("a PNG is the picture while the picture shows, Plotly's plot while Plotly does", async () => {
    const { plot, drawn, ops, come } = panelPlot();
    plot.update(0);
    plot.exportPng("joint-position-1");
    expect(drawn.at(-1)).toBe("png joint-position-1");
    expect(ops()).toEqual([]);
    plot.setPointerInside(true);
    await come();
    plot.exportPng("joint-position-2");
    expect(ops().at(-1)).toBe("downloadPng");
  });
});
