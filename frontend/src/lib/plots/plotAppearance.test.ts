// How a live plot looks (lib/plots/plotAppearance.ts): the time axis' choice (our own ticks on a
// linear axis for a static ring view, the date axis otherwise), a zoom in the layout, the
// config, trace styles, the markers and the per-axis revisions of a drawing of the recording.
import { describe, expect, it } from "vitest";
import {
  DEFAULT_PLOT_HEIGHT_PX,
  emptyTraces,
  hasSecondAxis,
  historyLayout,
  markerShapes,
  plotAreaWidth_px,
  plotConfig,
  plotLayout,
  ticksBefore,
  timeAxis,
  traceStyle,
  type PlotLook,
} from "./plotAppearance";
import type { Marker } from "./historyView";
import { JOINT_PLOTS, TCP_PLOTS, tracesOf } from "./plots";

type Axis = {
  type?: string;
  tickmode?: string;
  tickvals?: number[];
  ticktext?: string[];
  autorange?: boolean;
  range?: unknown[];
  gridcolor?: string;
  uirevision?: string;
};

const joints = JOINT_PLOTS[0]!;
const velocity = TCP_PLOTS.find((p) => p.id === "plot-tcp-velocity")!;
const light: PlotLook = { theme: "light", readOnly: false };
const T0 = Date.UTC(2026, 10, 24, 9, 0, 0);

describe("the plotting area", () => {
  it("is the element less the margins, wider on the right for a second axis", () => {
    expect(hasSecondAxis(joints)).toBe(false);
    expect(hasSecondAxis(velocity)).toBe(true);
    expect(plotAreaWidth_px(joints, 880)).toBe(880 - 64 - 16);
    expect(plotAreaWidth_px(velocity, 880)).toBe(880 - 64 - 64);
    expect(plotAreaWidth_px(joints, Number.NaN)).toBeNaN();
  });
});

describe("the time axis", () => {
  it("a static ring view: a linear axis with round-time ticks over the window before the newest frame", () => {
    const time = timeAxis(light, true, {}, T0, 10_000, 800);
    const axis = time.axis as Axis;
    expect(time.ownTicks).toBe(true);
    expect(time.range).toBeNull();
    expect(axis.type).toBe("linear");
    expect(axis.tickmode).toBe("array");
    expect(axis.autorange).toBe(true);
    expect(axis.tickvals).toEqual(ticksBefore(T0, 10_000, 800, undefined).tickvals);
    expect(Math.max(...axis.tickvals!)).toBeLessThanOrEqual(T0);
    expect(Math.min(...axis.tickvals!)).toBeGreaterThanOrEqual(T0 - 10_500);
    expect(axis.ticktext!.every((t) => /^\d\d:\d\d:\d\d$/.test(t))).toBe(true);
  });

  it("interactive or on the recording: Plotly's date axis, no ticks of ours", () => {
    const time = timeAxis({ theme: "dark", readOnly: false }, false, { xaxis: [1, 2] }, T0, 10_000, 800);
    expect(time.ownTicks).toBe(false);
    expect(time.range).toBeNull();
    expect(time.axis).toEqual({ autorange: true, gridcolor: "#2f3740", ticklabeloverflow: "allow", type: "date" });
  });

  it("a zoom carried over from the date axis: its range as numbers, ticks fixed on it", () => {
    const time = timeAxis(light, true, { xaxis: ["2026-11-24 09:00:02", T0 + 6000] }, T0 + 9000, 10_000, 800);
    expect(time.ownTicks).toBe(false);
    expect(time.range).toEqual([T0 + 2000, T0 + 6000]);
    const axis = time.axis as Axis;
    expect(axis.type).toBe("linear");
    expect(Math.min(...axis.tickvals!)).toBeGreaterThanOrEqual(T0 + 2000);
    expect(Math.max(...axis.tickvals!)).toBeLessThanOrEqual(T0 + 6000);
  });

  it("larger labels (the kiosk's) get fewer ticks", () => {
    const small = ticksBefore(T0, 120_000, 800, undefined).tickvals.length;
    const large = ticksBefore(T0, 120_000, 800, 24).tickvals.length;
    expect(large).toBeLessThan(small);
  });
});

describe("the layout and the config", () => {
  it("sets a zoom's ranges with autorange off, the time axis' own range included", () => {
    const time = timeAxis(light, true, { xaxis: [T0, T0 + 4000] }, T0, 10_000, 800);
    const layout = plotLayout(velocity, light, 3, false, time, { yaxis2: [0, 5] }) as Record<string, Axis> & {
      uirevision: string;
      hovermode: unknown;
      height: number;
    };
    expect(layout.uirevision).toBe("plot-tcp-velocity:3");
    expect(layout.hovermode).toBe(false);
    expect(layout.height).toBe(DEFAULT_PLOT_HEIGHT_PX);
    expect(layout.xaxis!.autorange).toBe(false);
    expect(layout.xaxis!.range).toEqual([T0, T0 + 4000]);
    expect(layout.yaxis!.autorange).toBe(true);
    expect(layout.yaxis2!.autorange).toBe(false);
    expect(layout.yaxis2!.range).toEqual([0, 5]);
  });

  it("hovers while interactive; one y axis without a second", () => {
    const time = timeAxis(light, false, {}, T0, 10_000, 800);
    const layout = plotLayout(joints, { ...light, height_px: 300 }, 0, true, time, {});
    expect(layout.hovermode).toBe("x");
    expect(layout.height).toBe(300);
    expect(layout.yaxis2).toBeUndefined();
    expect((layout.xaxis as Axis).autorange).toBe(true);
  });

  it("a static picture has no mode bar; an interactive plot no image button (the view has its own)", () => {
    expect(plotConfig(false)).toEqual({ staticPlot: true, displayModeBar: false, responsive: true });
    const interactive = plotConfig(true) as { staticPlot?: boolean; modeBarButtonsToRemove: string[] };
    expect(interactive.staticPlot).toBeUndefined();
    expect(interactive.modeBarButtonsToRemove).toContain("toImage");
    // Nothing of the cell goes to Plotly's cloud; no notice over the plot's header.
    expect(interactive.modeBarButtonsToRemove).toContain("sendChartToCloud");
    expect((interactive as { showTips?: boolean }).showTips).toBe(false);
  });
});

describe("trace styles", () => {
  it("the panel's are 1 px hairlines with the unit in the hover; the kiosk's heavier, no hover", () => {
    const traces = tracesOf(velocity);
    const panel = traceStyle(traces[0]!, 0, true, false) as { line: { width: number; dash: string }; hovertemplate?: string };
    expect(panel.line.width).toBe(1);
    expect(panel.line.dash).toBe("solid");
    expect(panel.hovertemplate).toContain("mm/s");
    const kiosk = traceStyle(traces[5]!, 5, false, true) as { line: { width: number; dash: string }; hoverinfo?: string; visible: boolean };
    expect(kiosk.line.width).toBe(1.5);
    expect(kiosk.line.dash).toBe("dot"); // the second axis' signals
    expect(kiosk.hoverinfo).toBe("skip");
    expect(kiosk.visible).toBe(false);
  });

  it("empty traces keep the signal picker's choice", () => {
    const traces = tracesOf(joints);
    const empty = emptyTraces(traces, [true, false], false) as { visible: boolean; x: unknown[] }[];
    expect(empty).toHaveLength(6);
    expect(empty.map((t) => t.visible)).toEqual([true, false, true, true, true, true]);
    expect(empty.every((t) => t.x.length === 0)).toBe(true);
  });
});

describe("a drawing of the recording", () => {
  it("markers are dotted lines across the plot, an alarm's in its colour", () => {
    const marker = (time_s: number, kind: Marker["kind"]): Marker => ({
      id: String(time_s),
      time_s,
      last_s: time_s,
      kind,
      label: kind,
      events: [],
      at: 0.5,
    });
    const shapes = markerShapes([marker(100, "alarm"), marker(200, "connection")], 60_000) as {
      x0: number;
      x1: number;
      yref: string;
      line: { color: string; dash: string };
    }[];
    expect(shapes.map((s) => [s.x0, s.x1])).toEqual([
      [40_000, 40_000],
      [140_000, 140_000],
    ]);
    expect(shapes.every((s) => s.yref === "paper" && s.line.dash === "dot")).toBe(true);
    expect(shapes.map((s) => s.line.color)).toEqual(["#D55E00", "#888"]);
  });

  it("each axis gets its own revision; the layout's (the drag mode) and the input are left alone", () => {
    const time = timeAxis(light, false, {}, T0, 10_000, 800);
    const base = plotLayout(velocity, light, 2, true, time, { xaxis: [T0, T0 + 1000] });
    const drawn = historyLayout(base, [], 4, 7) as Record<string, Axis> & { uirevision: string; shapes: unknown[] };
    expect(drawn.uirevision).toBe("plot-tcp-velocity:2");
    expect(drawn.xaxis!.uirevision).toBe("x4");
    expect(drawn.yaxis!.uirevision).toBe("y7");
    expect(drawn.yaxis2!.uirevision).toBe("y7");
    expect(drawn.xaxis!.range).toEqual([T0, T0 + 1000]);
    expect(drawn.shapes).toEqual([]);
    expect((base.xaxis as Axis).uirevision).toBeUndefined();
  });
});
