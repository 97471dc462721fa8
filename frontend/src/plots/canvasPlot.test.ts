// A live plot's canvas picture (plots/canvasPlot.ts), drawn on a recording fake context: the x
// range drawn is the points' own or the zoom's, a missing value breaks the line (never a
// bridge), a trace picked off is not drawn, extend keeps the newest points, and nothing is drawn
// before the canvas has a size.
import { describe, expect, it } from "vitest";
import { JOINT_PLOTS, tracesOf } from "../lib/plots/plots";
import { CanvasPlot, type PictureCanvas, type PictureContext } from "./canvasPlot";

const spec = JOINT_PLOTS[0]!;
const traces = tracesOf(spec);

function fakeCanvas() {
  const calls: { op: string; args: unknown[]; stroke?: unknown }[] = [];
  const ctx: Record<string, unknown> = { fillStyle: "", strokeStyle: "", lineWidth: 1, font: "", textAlign: "left", textBaseline: "top" };
  for (const op of ["setTransform", "fillRect", "beginPath", "moveTo", "lineTo", "stroke", "save", "restore", "rect", "clip", "setLineDash", "fillText"]) {
    ctx[op] = (...args: unknown[]) => calls.push({ op, args, stroke: ctx.strokeStyle });
  }
  const canvas: PictureCanvas = { width: 0, height: 0, getContext: () => ctx as unknown as PictureContext, style: { visibility: "" } };
  return { canvas, calls };
}

/** The line segments' starts (moveTo) in the plotting area, per stroke colour. */
const moves = (calls: { op: string; stroke?: unknown }[], colour: unknown) => calls.filter((c) => c.op === "moveTo" && c.stroke === colour).length;

describe("CanvasPlot", () => {
  const xs = traces.map(() => [1000, 2000, 3000, 4000]);
  const ys = traces.map((_, i) => [i, i + 1, null, i + 2]);

  it("draws the points over their own range, a missing value a break, nothing before a size", () => {
    const { canvas, calls } = fakeCanvas();
    const picture = new CanvasPlot(canvas, spec, traces, { theme: "light", readOnly: false });
    picture.reset(xs, ys);
    const all = traces.map(() => true);
    expect(picture.draw({ visible: all, x: null, y: {} })).toBeNull(); // no size yet
    picture.resize(880, 240, 2);
    expect([canvas.width, canvas.height]).toEqual([1760, 480]);
    expect(picture.draw({ visible: all, x: null, y: {} })).toEqual([1000, 4000]);
    // Trace 0: two pieces (1000–2000, then 4000 alone after the gap).
    const lineStart = calls.findIndex((c) => c.op === "clip");
    const lines = calls.slice(lineStart);
    const colour0 = lines.find((c) => c.op === "moveTo")!.stroke;
    expect(moves(lines, colour0)).toBe(2);
    expect(lines.filter((c) => c.op === "lineTo" && c.stroke === colour0)).toHaveLength(1);
  });

  it("honours the zoom's x range, leaves a trace picked off out, keeps the newest points", () => {
    const { canvas, calls } = fakeCanvas();
    const picture = new CanvasPlot(canvas, spec, traces, { theme: "dark", readOnly: false });
    picture.resize(880, 240, 1);
    picture.reset(xs, ys);
    picture.extend(traces.map(() => [5000]), traces.map(() => [9]), 4);
    const visible = traces.map((_, i) => i !== 0);
    expect(picture.draw({ visible, x: [2500, 4500], y: { yaxis: [0, 10] } })).toEqual([2500, 4500]);
    const lines = calls.slice(calls.findIndex((c) => c.op === "clip"));
    expect(lines.filter((c) => c.op === "stroke")).toHaveLength(traces.length - 1);
    // Unzoomed, the range is the newest four points': 2000 … 5000.
    expect(picture.draw({ visible, x: null, y: {} })).toEqual([2000, 5000]);
    picture.show(true);
    expect(canvas.style.visibility).toBe("visible");
    picture.show(false);
    expect(canvas.style.visibility).toBe("hidden");
  });

  it("hides the canvas off the screen, and shows it again in view while it is the picture", () => {
    const { canvas } = fakeCanvas();
    const picture = new CanvasPlot(canvas, spec, traces, { theme: "light", readOnly: false });
    picture.show(true);
    picture.setInView(false);
    expect(canvas.style.visibility).toBe("hidden");
    picture.setInView(true);
    expect(canvas.style.visibility).toBe("visible");
    picture.show(false); // Plotly draws (the pointer is on the plot): hidden in view too
    picture.setInView(true);
    expect(canvas.style.visibility).toBe("hidden");
  });
});
