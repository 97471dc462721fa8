/**
 * Layer: the one module that imports Plotly (its partial "basic" bundle: scatter only).
 * It adapts Plotly to `PlotBackend`; nothing else in the app calls Plotly directly.
 */
import Plotly from "plotly.js-basic-dist-min";
import type { PlotBackend } from "./plotBackend";

function ignore(promise: Promise<unknown>): void {
  // Plotly's promises reject only when the element was purged meanwhile: nothing to do.
  promise.catch(() => undefined);
}

export const plotlyBackend: PlotBackend = {
  newPlot(el, data, layout, config) {
    ignore(Plotly.newPlot(el, data as never, layout as never, config as never));
  },
  react(el, data, layout, config) {
    ignore(Plotly.react(el, data as never, layout as never, config as never));
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
    ignore(Plotly.extendTraces(el, update, indices, maxPoints));
  },
  restyle(el, update, indices) {
    ignore(Plotly.restyle(el, update as never, indices));
  },
  relayout(el, update) {
    ignore(Plotly.relayout(el, update as never));
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
    ignore(Plotly.downloadImage(el, { format: "png", filename, width: el.clientWidth, height: el.clientHeight }));
  },
  purge(el) {
    Plotly.purge(el);
  },
};
