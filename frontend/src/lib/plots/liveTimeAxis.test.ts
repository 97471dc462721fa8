// A live plot's time axis (lib/plots/plotting.ts, lib/plots/timeTicks.ts): our own ticks on a linear axis
// while it is a static picture, moved in the same redraw as each extendTraces; the date axis
// while interactive; a zoom carried over from the date axis.
import { describe, expect, it } from "vitest";
import { setupPlot as setup } from "./plotTestSupport";

type Axis = { type?: string; tickmode?: string; tickvals?: number[]; ticktext?: string[]; autorange?: boolean; range?: unknown[] };
type Layout = { xaxis: Axis };

const T0 = Date.UTC(2026, 10, 24, 9, 0, 0);

describe("a live plot's time axis", () => {
  it("is a linear axis with round-time ticks while static, moved with each extendTraces", () => {
    const { backend, plot, push } = setup();
    for (let t = 0; t < 10_000; t += 10) push(T0 + t);
    plot.update(0); // the first drawing: the whole window
    const built = backend.calls.at(-1)!;
    expect(built.op).toBe("react");
    const axis = (built.args[2] as Layout).xaxis;
    expect(axis.type).toBe("linear");
    expect(axis.tickmode).toBe("array");
    expect(axis.autorange).toBe(true);
    expect(axis.tickvals!.length).toBeGreaterThanOrEqual(2);
    expect(axis.ticktext!.every((t) => /^\d\d:\d\d:\d\d$/.test(t))).toBe(true);

    for (let t = 10_000; t < 12_000; t += 10) push(T0 + t);
    expect(plot.update(1)).toBe(true);
    const extend = backend.calls.at(-1)!;
    expect(extend.op).toBe("extendTraces");
    const ticks = (extend.args[4] as { xaxis: Axis }).xaxis;
    // The ticks follow the newest sample (shifted to local time as the x values are).
    const xs = (extend.args[1] as { x: number[][] }).x[0]!;
    const newest = xs[xs.length - 1]!;
    expect(Math.max(...ticks.tickvals!)).toBeLessThanOrEqual(newest);
    expect(Math.max(...ticks.tickvals!)).toBeGreaterThan(newest - 3000);
    expect(ticks.ticktext).toHaveLength(ticks.tickvals!.length);
  });

  it("is Plotly's date axis while interactive, and extendTraces then leaves the axis alone", () => {
    const { backend, plot, push } = setup();
    for (let t = 0; t < 5000; t += 10) push(T0 + t);
    plot.update(0);
    plot.setPointerInside(true);
    const interactive = backend.calls.at(-1)!;
    expect(interactive.op).toBe("react");
    expect((interactive.args[2] as Layout).xaxis.type).toBe("date");
    expect((interactive.args[2] as Layout).xaxis.tickmode).toBeUndefined();
    for (let t = 5000; t < 6000; t += 10) push(T0 + t);
    plot.update(1);
    expect(backend.calls.at(-1)!.op).toBe("extendTraces");
    expect(backend.calls.at(-1)!.args[4]).toBeUndefined();
  });

  it("keeps a zoom made on the date axis when the plot turns static, its ticks fixed on it", () => {
    const { backend, plot, push } = setup();
    for (let t = 0; t < 8000; t += 10) push(T0 + t);
    plot.update(0);
    plot.setPointerInside(true);
    // A person's zoom: Plotly keeps a date axis' range as text.
    backend.zoom.xaxis = ["2026-11-24 09:00:02", "2026-11-24 09:00:06"];
    plot.setPointerInside(false);
    const rebuilt = backend.calls.at(-1)!;
    expect(rebuilt.op).toBe("react");
    const axis = (rebuilt.args[2] as Layout).xaxis;
    expect(axis.type).toBe("linear");
    expect(axis.autorange).toBe(false);
    expect(axis.range).toEqual([Date.UTC(2026, 10, 24, 9, 0, 2), Date.UTC(2026, 10, 24, 9, 0, 6)]);
    expect(axis.ticktext!.length).toBeGreaterThanOrEqual(2);
    // Data keeps coming, the zoomed axis stays where the person put it.
    for (let t = 8000; t < 9000; t += 10) push(T0 + t);
    plot.update(1);
    expect(backend.calls.at(-1)!.op).toBe("extendTraces");
    expect(backend.calls.at(-1)!.args[4]).toBeUndefined();
  });
});
