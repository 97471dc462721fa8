/**
 * Layer: pure mapping from the robot-state value to what the state badge shows.
 *
 * Names, descriptions and teach-pendant colours come from the generated layout's state table;
 * this module only adds how a pendant colour looks on screen. Must not import React or the DOM.
 */
import { LAYOUT, UNKNOWN_STATE_NAME } from "../../generated/layout";

/** How a teach-pendant colour name is painted: background and a readable text colour on it. */
export interface Paint {
  readonly background: string;
  readonly text: string;
}

const PAINTS: Readonly<Record<string, Paint>> = {
  white: { background: "#f4f4f2", text: "#111111" },
  green: { background: "#1f9d48", text: "#ffffff" },
  yellow: { background: "#f5c400", text: "#111111" },
  red: { background: "#d32020", text: "#ffffff" },
  blue: { background: "#1f5fc7", text: "#ffffff" },
};

/** Paint of a state the layout does not know, or of no state at all: neutral, never "OK". */
export const UNKNOWN_PAINT: Paint = { background: "#6b6b6b", text: "#ffffff" };

export function paintOf(colour: string): Paint {
  return PAINTS[colour] ?? UNKNOWN_PAINT;
}

export interface StateBadgeView {
  /** The state value the robot reported, or null before the first frame. */
  readonly value: number | null;
  /** The layout's state name, UNKNOWN for a value it does not define, NO DATA before a frame. */
  readonly name: string;
  /** The state in plain words for people ("Standalone running"), from the layout. */
  readonly label: string;
  /** The layout's description, shown as the badge's tooltip. */
  readonly description: string;
  /** Pendant colour names in display order; two or more alternate ("in turn"). */
  readonly colours: readonly string[];
  readonly paints: readonly Paint[];
  readonly alternating: boolean;
  readonly known: boolean;
}

export const NO_DATA_NAME = "NO DATA";
/** What the badge says before a frame and for a value the layout does not define. */
export const NO_DATA_LABEL = "No data";
export const UNKNOWN_LABEL = "Unknown state";

/** The tooltip of a state: its description, then the enum name the API and the robot use. */
export function stateTooltip(view: StateBadgeView): string {
  return view.known ? `${view.description} (${view.name})` : view.description;
}

const BY_VALUE = new Map(LAYOUT.robot_states.map((s) => [s.value, s]));

/** What the badge shows for the robot-state value `value` (null: no frame yet). */
export function stateBadge(value: number | null | undefined): StateBadgeView {
  if (value === null || value === undefined) {
    return {
      value: null,
      name: NO_DATA_NAME,
      label: NO_DATA_LABEL,
      description: "No frame has been received from the robot yet.",
      colours: [],
      paints: [UNKNOWN_PAINT],
      alternating: false,
      known: false,
    };
  }
  const info = BY_VALUE.get(value);
  if (info === undefined) {
    return {
      value,
      name: UNKNOWN_STATE_NAME,
      label: UNKNOWN_LABEL,
      description: `The robot reported state value ${value}, which the layout does not define.`,
      colours: [],
      paints: [UNKNOWN_PAINT],
      alternating: false,
      known: false,
    };
  }
  return {
    value,
    name: info.name,
    label: info.label,
    description: info.description,
    colours: info.pendant_colours,
    paints: info.pendant_colours.map(paintOf),
    alternating: info.pendant_colours.length > 1,
    known: true,
  };
}

/** The value of the emergency-stop state, from the layout (used to make sure it is never hidden). */
export const EMERGENCY_STOP_VALUE: number | null =
  LAYOUT.robot_states.find((s) => s.name === "EMERGENCY_STOP")?.value ?? null;
