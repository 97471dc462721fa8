/**
 * Layer: pure (no DOM, no React). A live plot's time-axis buttons and keys
 * (components/LivePlotView.tsx): the steps of lib/plots/plotSteps.ts, the cursor's keys.
 */
import type { PlotStep } from "../lib/plots/plotSteps";

/**
 * The time-axis buttons (keyboard and touch: the same steps as a person's zoom and pan with the
 * mouse, lib/plots/plotSteps.ts), each with its key on the focused plotting area.
 */
export const STEP_BUTTONS: readonly { step: PlotStep; text: string; label: string; title: string }[] = [
  { step: "zoomIn", text: "+", label: "Zoom in", title: "Zoom in: half the time range (key +; Ctrl + mouse wheel)" },
  { step: "zoomOut", text: "−", label: "Zoom out", title: "Zoom out: twice the time range, back into the recording (key −; Ctrl + mouse wheel)" },
  { step: "earlier", text: "◀", label: "Earlier", title: "Earlier: half a range back in time (key ←)" },
  { step: "later", text: "▶", label: "Later", title: "Later: half a range on; onto now is back to live (key →)" },
];

/** What a key pressed on the focused plotting area does: a step, a move of the cursor, or nothing. */
export type PlotKeyAction = { readonly step: PlotStep } | { readonly cursor: -1 | 1 } | null;

/** The action of `key` (with Shift held or not) on the focused plotting area. */
export function plotKeyAction(key: string, shift: boolean): PlotKeyAction {
  if (shift && key === "ArrowLeft") return { cursor: -1 };
  if (shift && key === "ArrowRight") return { cursor: 1 };
  switch (key) {
    case "+":
    case "=":
      return { step: "zoomIn" };
    case "-":
    case "_":
      return { step: "zoomOut" };
    case "ArrowLeft":
      return { step: "earlier" };
    case "ArrowRight":
      return { step: "later" };
    default:
      return null;
  }
}
