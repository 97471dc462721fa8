/**
 * Layer: pure definitions of the panel's custom plots (no React, no DOM, no Plotly).
 *
 * The signal picker puts any numeric field of any robot into a plot of its own: the robot's name,
 * the field (all its channels; each can be hidden in the plot), from the layout's numeric frame
 * fields. Each custom plot gets its own stream of that robot (lib/stream/runtime.ts) and shares the
 * page's plot coordinator, so its redraws take turns with the others'.
 */
import type { FrameFieldName } from "../../generated/layout";
import { TILE_FIELDS } from "../kiosk/kioskTiles";
import type { PlotSpec } from "./plots";

/** Fields the picker offers: every number the frame carries (not bits, not the state). */
export const PICKABLE_FIELDS = TILE_FIELDS;

/** At most this many custom plots at once (each holds a stream). */
export const MAX_CUSTOM_PLOTS = 4;

/** Frames per second a custom plot's stream asks for (the plots need no more). */
export const CUSTOM_PLOT_RATE_HZ = 50;

export interface CustomPlot {
  readonly robot: string;
  readonly field: FrameFieldName;
  readonly spec: PlotSpec;
}

export function isPickable(name: string): name is FrameFieldName {
  return PICKABLE_FIELDS.some((f) => f.name === name);
}

/** A custom plot of `field` of `robot`; `serial` keeps the test ids of plots apart. */
export function customPlot(robot: string, field: FrameFieldName, serial: number): CustomPlot {
  const info = PICKABLE_FIELDS.find((f) => f.name === field);
  if (info === undefined) throw new Error(`${field} is not a numeric field of the frame`);
  const words = info.description.replace(/^(Joint|TCP) (1–6 )?/i, "").trim() || info.name;
  return {
    robot,
    field,
    spec: {
      id: `plot-custom-${serial}`,
      title: `${robot} · ${info.description}`,
      series: [{ field, label: words, axis: "y" }],
    },
  };
}

/** Why a new custom plot cannot be added now, or null. */
export function refuseNewPlot(plots: readonly CustomPlot[], robot: string | null, field: string | null): string | null {
  if (robot === null || robot === "") return "Choose a robot.";
  if (field === null || field === "") return "Choose a signal.";
  if (!isPickable(field)) return `${field} is not a numeric field of the frame.`;
  if (plots.length >= MAX_CUSTOM_PLOTS) return `At most ${MAX_CUSTOM_PLOTS} custom plots; remove one first.`;
  if (plots.some((p) => p.robot === robot && p.field === field)) return "That signal of that robot is already plotted.";
  return null;
}
