/**
 * Layer: the one module that imports Plotly (its partial "basic" bundle: scatter only).
 * It adapts Plotly to `PlotBackend`; nothing else in the app calls Plotly directly.
 *
 * Plotly comes in its own chunk, loaded the first time a plot asks for it (`load`): a live plot
 * nobody points at is the canvas picture (plots/canvasPlot.ts), so the kiosk never loads Plotly
 * and the panel only when a person first points at a plot, focuses one, or shows the recording.
 * Plotly's module and six empty plots cost the panel's page about a second of the main thread
 * at every load on the 2-core machine (944 ms of script of 1.8 s busy), and its SVGs 1,200 of
 * the page's 4,300 elements. The drawing calls are made only once `ready()`.
 */
import type { PlotBackend } from "./plotBackend";

type PlotlyModule = typeof import("plotly.js-basic-dist-min").default;

let plotly: PlotlyModule | null = null;
let loading: Promise<void> | null = null;

function load(): Promise<void> {
  loading ??= import("plotly.js-basic-dist-min").then(
    (module) => {
      plotly = module.default;
    },
    (error: unknown) => {
      // Asked again at the next need (a chunk the server could not give this time).
      loading = null;
      throw error;
    },
  );
  return loading;
}

/** Plotly, which the callers only reach once `ready()` says it has come. */
function loaded(): PlotlyModule {
  if (plotly === null) throw new Error("Plotly asked to draw before it was loaded (PlotBackend.load)");
  return plotly;
}

function ignore(promise: Promise<unknown>): void {
  // Plotly's promises reject only when the element was purged meanwhile: nothing to do.
  promise.catch(() => undefined);
}

export const plotlyBackend: PlotBackend = {
  ready: () => plotly !== null,
  load,
  newPlot(el, data, layout, config) {
    ignore(loaded().newPlot(el, data as never, layout as never, config as never));
  },
  react(el, data, layout, config) {
    ignore(loaded().react(el, data as never, layout as never, config as never));
  },
  extendTraces(el, update, indices, maxPoints, axes) {
    if (axes !== undefined) {
      // extendTraces redraws the whole plot from the element's layout (Plotly.redraw, plotly.js
      // issue #2358): axis attributes set there now are drawn by that one redraw, where a
      // relayout would be a second one (Plotly's docs on `redraw`: mutate, then redraw).
      const layout = (el as HTMLElement & { layout?: Record<string, unknown> }).layout;
      for (const [name, attributes] of Object.entries(axes)) {
        const axis = layout?.[name];
        if (typeof axis === "object" && axis !== null) Object.assign(axis, attributes);
      }
    }
    ignore(loaded().extendTraces(el, update, indices, maxPoints));
  },
  restyle(el, update, indices) {
    ignore(loaded().restyle(el, update as never, indices));
  },
  relayout(el, update) {
    ignore(loaded().relayout(el, update as never));
  },
  zoomedAxes(el) {
    const layout = (el as HTMLElement & { layout?: Record<string, unknown> }).layout ?? {};
    const zoomed: Record<string, readonly unknown[]> = {};
    for (const axis of ["xaxis", "yaxis", "yaxis2"]) {
      const a = layout[axis] as { autorange?: unknown; range?: unknown } | undefined;
      if (a !== undefined && a.autorange === false && Array.isArray(a.range) && a.range.length === 2) {
        zoomed[axis] = a.range as unknown[];
      }
    }
    return zoomed;
  },
  onRelayout(el, listener) {
    // Plotly adds `on` to the element it plotted into (an EventEmitter); relayout is a person's
    // zoom, pan, autoscale or reset (and our own relayout calls, none while live).
    (el as HTMLElement & { on?: (event: string, cb: () => void) => void }).on?.("plotly_relayout", listener);
  },
  downloadPng(el, filename) {
    ignore(loaded().downloadImage(el, { format: "png", filename, width: el.clientWidth, height: el.clientHeight }));
  },
  purge(el) {
    // Never drawn by Plotly when it has not come.
    plotly?.purge(el);
  },
};
