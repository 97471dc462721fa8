/**
 * The robot-state badge: the state in plain words from the layout ("Standalone running"), pendant
 * colours (alternating for two); the description and the enum name (what the API says) in the
 * tooltip and in `data-state-name`.
 */
import type { CSSProperties } from "react";
import { stateBadge, stateTooltip } from "../lib/layout/stateBadge";

interface Props {
  readonly value: number | null | undefined;
  readonly stale: boolean;
  readonly size: "panel" | "kiosk";
}

export function StateBadge({ value, stale, size }: Props) {
  const badge = stateBadge(value);
  const first = badge.paints[0];
  const second = badge.paints[1] ?? first;
  const style = {
    "--badge-bg-0": first?.background,
    "--badge-fg-0": first?.text,
    "--badge-bg-1": second?.background,
    "--badge-fg-1": second?.text,
    // Lets the kiosk size the longest labels (29 characters) to the screen's width.
    "--name-length": Math.max(badge.label.length, 12),
  } as CSSProperties;
  const classes = ["state-badge", `state-badge--${size}`];
  if (badge.alternating) classes.push("state-badge--alternating");
  if (!badge.known) classes.push("state-badge--unknown");
  if (stale) classes.push("is-stale");
  const tooltip = stateTooltip(badge);
  return (
    <div
      className={classes.join(" ")}
      style={style}
      data-testid="robot-state"
      data-state-name={badge.name}
      data-state-value={badge.value ?? ""}
      data-colours={badge.colours.join(" ")}
      data-stale={stale ? "true" : "false"}
      title={tooltip}
      role="status"
      aria-label={`Robot state ${badge.label}${stale ? " (stale)" : ""}: ${tooltip}`}
    >
      {badge.label}
    </div>
  );
}
