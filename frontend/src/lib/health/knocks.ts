/**
 * Layer: pure geometry of the knocks' joint-space picture (no React, no DOM): one vertical axis
 * per joint (its range, −limit at the bottom to +limit at the top, from the arm table), and each
 * knock a line through the six positions the arm had when it happened (parallel coordinates), so
 * knocks at the same place of the program lie on top of each other. Also the knocks' words.
 */
import type { KnockEvent, Knocks } from "./healthTypes";

/** The knocks' kinds (docs/health.md "Knocks"), in words and with a colour and a dash of their own. */
export const KNOCK_KINDS: Readonly<Record<string, { readonly words: string; readonly colour: string; readonly dash: string }>> = {
  collision: { words: "external-torque peak", colour: "#b71c1c", dash: "" },
  protective_stop: { words: "protective stop", colour: "#b35c00", dash: "6 3" },
  emergency_stop: { words: "emergency stop", colour: "#6a1b9a", dash: "2 2" },
  servo_off: { words: "servo off", colour: "#4a5561", dash: "8 2 2 2" },
};

export function knockKindWords(kind: string): string {
  return KNOCK_KINDS[kind]?.words ?? kind.replace(/_/g, " ");
}

/** "external-torque peak on J3, 42.0 N·m", "protective stop". */
export function knockWords(event: Pick<KnockEvent, "kind" | "joint" | "external_torque_nm">): string {
  const kind = knockKindWords(event.kind);
  const on = event.joint !== null && event.joint !== undefined ? ` on J${event.joint}` : "";
  const peak = typeof event.external_torque_nm === "number" ? `, ${Math.abs(event.external_torque_nm).toFixed(1)} N·m` : "";
  return `${kind}${on}${peak}`;
}

/** This shift's knocks in a line: "3 external-torque peaks (J3: 2, J5: 1), 1 protective stop". */
export function knockCountsWords(knocks: Knocks | null | undefined): string {
  if (knocks === null || knocks === undefined) return "not known";
  const parts: string[] = [];
  const collisions = knocks.collisions ?? [];
  const total = collisions.reduce((a, b) => a + b, 0);
  if (total > 0) {
    const per = collisions.flatMap((c, i) => (c > 0 ? [`J${i + 1}: ${c}`] : []));
    parts.push(`${total} external-torque peak${total === 1 ? "" : "s"} (${per.join(", ")})`);
  }
  for (const [key, words] of [
    ["protective_stop", "protective stop"],
    ["emergency_stop", "emergency stop"],
    ["servo_off", "servo off"],
  ] as const) {
    const n = knocks[key] ?? 0;
    if (n > 0) parts.push(`${n} ${words}${n === 1 ? "" : "s"}`);
  }
  return parts.length === 0 ? "none this shift" : parts.join(", ");
}

export interface PictureAxis {
  readonly joint: number;
  readonly x: number;
  readonly limit_deg: number;
}

export interface PictureLine {
  readonly event: KnockEvent;
  /** SVG polyline points ("x,y x,y …"), one per joint. */
  readonly points: string;
  readonly colour: string;
  readonly dash: string;
}

export interface KnockPicture {
  readonly width: number;
  readonly height: number;
  /** The plotting area's top and bottom (y of +limit and of −limit). */
  readonly top: number;
  readonly bottom: number;
  readonly axes: readonly PictureAxis[];
  readonly lines: readonly PictureLine[];
}

/** The y of `position_deg` on an axis of ±`limit_deg` (clamped to the axis). */
export function axisY(position_deg: number, limit_deg: number, top: number, bottom: number): number {
  const fraction = Math.min(1, Math.max(0, (position_deg + limit_deg) / (2 * limit_deg)));
  return bottom - fraction * (bottom - top);
}

/**
 * The picture of `events` on an arm whose joints turn ±`limits_deg` (J1 first), in a box of
 * `width` × `height` user units with room for the labels. Events with fewer positions than
 * joints are drawn over the joints they have.
 */
export function knockPicture(events: readonly KnockEvent[], limits_deg: readonly number[], width = 600, height = 260): KnockPicture {
  // Room for the axes' labels ("−360°") either side of the outer axes.
  const left = 48;
  const right = 40;
  const top = 24;
  const bottom = height - 28;
  const n = limits_deg.length;
  const step = n > 1 ? (width - left - right) / (n - 1) : 0;
  const axes = limits_deg.map((limit_deg, i) => ({ joint: i + 1, x: left + i * step, limit_deg }));
  const lines = events.map((event) => {
    const style = KNOCK_KINDS[event.kind] ?? { colour: "#4a5561", dash: "" };
    const points = axes
      .filter((axis) => Number.isFinite(event.joint_position_deg[axis.joint - 1]))
      .map((axis) => `${axis.x.toFixed(1)},${axisY(event.joint_position_deg[axis.joint - 1] as number, axis.limit_deg, top, bottom).toFixed(1)}`)
      .join(" ");
    return { event, points, colour: style.colour, dash: style.dash };
  });
  return { width, height, top, bottom, axes, lines };
}
