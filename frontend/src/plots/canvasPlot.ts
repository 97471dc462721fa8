/**
 * Layer: a live plot's static picture on a 2D canvas (DOM canvas only; no Plotly, no React).
 *
 * While nobody points at a live plot of the panel it is a picture, redrawn ten times a second
 * with the newest buckets. Plotly's `extendTraces` redraws the whole plot (its defaults, calc,
 * axes and SVG: about 7 ms a plot on the 2-core machine, six plots ten times a second being the
 * panel's main-thread load); this draws the same picture (the same margins, colours, 1 px lines,
 * our own time ticks, Plotly's autorange and round value ticks) as a few canvas paths in well
 * under a millisecond, and nothing of it enters the DOM. Under the pointer or the keyboard's
 * focus the plot turns into Plotly's interactive plot (zoom, pan) on the same axes.
 * lib/plots/plotting.ts drives it through `StaticPicture` (lib/plots/plotBackend.ts).
 */
import {
  PLOT_FONT_FAMILY,
  fontSize_px,
  hasSecondAxis,
  plotColours,
  plotMargin,
  ticksOver,
  type PlotLook,
  type PlotMargin,
} from "../lib/plots/plotAppearance";
import type { PictureDrawing, StaticPicture } from "../lib/plots/plotBackend";
import { traceColour, type PlotSpec, type TraceInfo } from "../lib/plots/plots";
import { paddedRange, valueTicks } from "./valueTicks";

type Datum = number | null;

/** What the picture draws with (a canvas' 2D context; a recording fake in the tests). */
export type PictureContext = Pick<
  CanvasRenderingContext2D,
  | "setTransform"
  | "fillRect"
  | "beginPath"
  | "moveTo"
  | "lineTo"
  | "stroke"
  | "save"
  | "restore"
  | "rect"
  | "clip"
  | "setLineDash"
  | "fillText"
> & {
  fillStyle: unknown;
  strokeStyle: unknown;
  lineWidth: number;
  font: string;
  textAlign: CanvasTextAlign;
  textBaseline: CanvasTextBaseline;
};

/** The canvas (its backing store's size in device pixels, and its context). */
export interface PictureCanvas {
  width: number;
  height: number;
  getContext(kind: "2d"): PictureContext | null;
  readonly style: { visibility: string };
  /** The picture as an image file (a page's canvas; the tests' fakes have none). */
  toBlob?(callback: (blob: Blob | null) => void, type?: string): void;
}

interface Area {
  readonly x: number;
  readonly y: number;
  readonly w: number;
  readonly h: number;
}

/** The [min, max] of the visible traces' finite values on `axis` (NaN, NaN: none). */
function extentOf(ys: readonly Datum[][], traces: readonly TraceInfo[], visible: readonly boolean[], axis: "y" | "y2"): [number, number] {
  let min = Infinity;
  let max = -Infinity;
  ys.forEach((values, i) => {
    if (traces[i]?.axis !== axis || visible[i] === false) return;
    for (const v of values) {
      if (v === null || !Number.isFinite(v)) continue;
      if (v < min) min = v;
      if (v > max) max = v;
    }
  });
  return min <= max ? [min, max] : [Number.NaN, Number.NaN];
}

export class CanvasPlot implements StaticPicture {
  private readonly canvas: PictureCanvas;
  private readonly traces: readonly TraceInfo[];
  private readonly look: PlotLook;
  private readonly margin: PlotMargin;
  private readonly twoAxes: boolean;
  private xs: number[][];
  private ys: Datum[][];
  private width_px = 0;
  private height_px = 0;
  private pixelRatio = 1;

  /** Shown over Plotly's plot (the plot is a static picture now). */
  private shown = false;

  /** On the page's screen or near it (components/LivePlotView.tsx watches). */
  private inView = true;

  constructor(canvas: PictureCanvas, spec: PlotSpec, traces: readonly TraceInfo[], look: PlotLook) {
    this.canvas = canvas;
    this.traces = traces;
    this.look = look;
    this.twoAxes = hasSecondAxis(spec);
    this.margin = plotMargin(this.twoAxes);
    this.xs = traces.map(() => []);
    this.ys = traces.map(() => []);
  }

  /** The canvas' size on the page (CSS px) and the device's pixels per CSS px. */
  resize(width_px: number, height_px: number, pixelRatio: number): void {
    this.width_px = width_px;
    this.height_px = height_px;
    this.pixelRatio = pixelRatio > 0 ? pixelRatio : 1;
    this.canvas.width = Math.max(1, Math.round(width_px * this.pixelRatio));
    this.canvas.height = Math.max(1, Math.round(height_px * this.pixelRatio));
  }

  reset(xs: readonly number[][], ys: readonly Datum[][]): void {
    this.xs = this.traces.map((_, i) => [...(xs[i] ?? [])]);
    this.ys = this.traces.map((_, i) => [...(ys[i] ?? [])]);
  }

  extend(xs: readonly number[][], ys: readonly Datum[][], maxPoints: number): void {
    this.traces.forEach((_, i) => {
      const x = this.xs[i] as number[];
      const y = this.ys[i] as Datum[];
      for (const v of xs[i] ?? []) x.push(v);
      for (const v of ys[i] ?? []) y.push(v);
      if (x.length > maxPoints) x.splice(0, x.length - maxPoints);
      if (y.length > maxPoints) y.splice(0, y.length - maxPoints);
    });
  }

  /** Save the picture as drawn now as `filename`.png (what the person sees, axes and all). */
  savePng(filename: string): void {
    this.canvas.toBlob?.((blob) => {
      if (blob === null) return;
      const url = URL.createObjectURL(blob);
      const link = document.createElement("a");
      link.href = url;
      link.download = `${filename}.png`;
      link.click();
      setTimeout(() => URL.revokeObjectURL(url), 0);
    }, "image/png");
  }

  show(on: boolean): void {
    this.shown = on;
    this.applyVisibility();
  }

  /**
   * Off the screen the canvas is hidden too: the compositor takes every visible canvas' picture
   * again with each commit of the page, changed or not (about 0.1 ms and a copy of its pixels
   * each in this software-rendered Chromium, ten plots at every commit); a hidden one it skips.
   */
  setInView(inView: boolean): void {
    this.inView = inView;
    this.applyVisibility();
  }

  private applyVisibility(): void {
    const visibility = this.shown && this.inView ? "visible" : "hidden";
    if (this.canvas.style.visibility !== visibility) this.canvas.style.visibility = visibility;
  }

  /** The x range of the visible traces' points (numeric dates), or null when they hold none. */
  private dataRange(visible: readonly boolean[]): [number, number] | null {
    let from = Infinity;
    let to = -Infinity;
    this.xs.forEach((x, i) => {
      if (visible[i] === false || x.length === 0) return;
      from = Math.min(from, x[0] as number);
      to = Math.max(to, x[x.length - 1] as number);
    });
    return to > from ? [from, to] : null;
  }

  draw(drawing: PictureDrawing): readonly [number, number] | null {
    const ctx = this.canvas.getContext("2d");
    if (ctx === null || !(this.width_px > 0) || !(this.height_px > 0)) return null;
    const colours = plotColours(this.look.theme);
    const m = this.margin;
    const area: Area = { x: m.l, y: m.t, w: this.width_px - m.l - m.r, h: this.height_px - m.t - m.b };
    ctx.setTransform(this.pixelRatio, 0, 0, this.pixelRatio, 0, 0);
    ctx.fillStyle = colours.paper;
    ctx.fillRect(0, 0, this.width_px, this.height_px);
    const x = drawing.x ?? this.dataRange(drawing.visible);
    if (x === null || !(x[1] > x[0]) || !(area.w > 0) || !(area.h > 0)) return null;
    const y = drawing.y.yaxis ?? paddedRange(...extentOf(this.ys, this.traces, drawing.visible, "y"));
    const y2 = drawing.y.yaxis2 ?? paddedRange(...extentOf(this.ys, this.traces, drawing.visible, "y2"));
    const size = fontSize_px(this.look);
    ctx.font = `${size}px ${PLOT_FONT_FAMILY}`;
    ctx.fillStyle = colours.text;
    ctx.strokeStyle = colours.grid;
    ctx.lineWidth = 1;
    ctx.setLineDash([]);
    // The grid and the time axis' labels under it.
    const time = ticksOver(x[0], x[1], area.w, this.look.fontSize_px);
    ctx.textAlign = "center";
    ctx.textBaseline = "top";
    ctx.beginPath();
    time.tickvals.forEach((t, k) => {
      const px = Math.round(area.x + ((t - x[0]) / (x[1] - x[0])) * area.w) + 0.5;
      ctx.moveTo(px, area.y);
      ctx.lineTo(px, area.y + area.h);
      ctx.fillText(time.ticktext[k] ?? "", px, area.y + area.h + 4);
    });
    const left = valueTicks(y[0], y[1], area.h);
    ctx.textAlign = "right";
    ctx.textBaseline = "middle";
    left.values.forEach((v, k) => {
      const py = Math.round(area.y + area.h - ((v - y[0]) / (y[1] - y[0])) * area.h) + 0.5;
      ctx.moveTo(area.x, py);
      ctx.lineTo(area.x + area.w, py);
      ctx.fillText(left.labels[k] ?? "", area.x - 4, py);
    });
    ctx.stroke();
    if (this.twoAxes) {
      const right = valueTicks(y2[0], y2[1], area.h);
      ctx.textAlign = "left";
      right.values.forEach((v, k) => {
        const py = area.y + area.h - ((v - y2[0]) / (y2[1] - y2[0])) * area.h;
        ctx.fillText(right.labels[k] ?? "", area.x + area.w + 4, py);
      });
    }
    ctx.save();
    ctx.beginPath();
    ctx.rect(area.x, area.y, area.w, area.h);
    ctx.clip();
    this.traces.forEach((trace, i) => {
      if (drawing.visible[i] === false) return;
      this.stroke(ctx, i, area, x, trace.axis === "y2" ? y2 : y, trace.axis === "y2");
    });
    ctx.restore();
    return x;
  }

  /** Trace `i` as one path, broken where a value is missing (a gap is shown, never bridged). */
  private stroke(ctx: PictureContext, i: number, area: Area, x: readonly number[], y: readonly number[], dotted: boolean): void {
    const xs = this.xs[i] as number[];
    const ys = this.ys[i] as Datum[];
    const sx = area.w / ((x[1] as number) - (x[0] as number));
    const sy = area.h / ((y[1] as number) - (y[0] as number));
    const x0 = x[0] as number;
    const y0 = y[0] as number;
    const bottom = area.y + area.h;
    ctx.strokeStyle = traceColour(i);
    ctx.lineWidth = this.look.readOnly ? 1.5 : 1;
    ctx.setLineDash(dotted ? [3, 3] : []);
    ctx.beginPath();
    let pen = false;
    for (let k = 0; k < xs.length; k++) {
      const v = ys[k];
      if (v === null || v === undefined || !Number.isFinite(v)) {
        pen = false;
        continue;
      }
      const px = area.x + ((xs[k] as number) - x0) * sx;
      const py = bottom - (v - y0) * sy;
      if (pen) ctx.lineTo(px, py);
      else ctx.moveTo(px, py);
      pen = true;
    }
    ctx.stroke();
  }
}

/**
 * Keep `picture` the size of `area` (CSS px, at the device's pixels per CSS px) from now on;
 * `resized` is called after each change (the plot draws the picture again). Returns the undo.
 */
export function followAreaSize(picture: CanvasPlot, area: HTMLElement, resized: () => void): () => void {
  const size = () => {
    picture.resize(area.clientWidth, area.clientHeight, window.devicePixelRatio || 1);
    resized();
  };
  size();
  if (typeof ResizeObserver === "undefined") return () => {};
  const observer = new ResizeObserver(size);
  observer.observe(area);
  return () => observer.disconnect();
}
