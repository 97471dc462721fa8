/** The robot-state badge: the layout's name, pendant colours (alternating for two), description as tooltip. */
import { Fragment, type CSSProperties } from "react";
import { stateBadge } from "../lib/stateBadge";

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
    // Lets the kiosk size the longest names (28 characters) to the screen's width.
    "--name-length": Math.max(badge.name.length, 12),
  } as CSSProperties;
  const classes = ["state-badge", `state-badge--${size}`];
  if (badge.alternating) classes.push("state-badge--alternating");
  if (!badge.known) classes.push("state-badge--unknown");
  if (stale) classes.push("is-stale");
  return (
    <div
      className={classes.join(" ")}
      style={style}
      data-testid="robot-state"
      data-state-name={badge.name}
      data-state-value={badge.value ?? ""}
      data-colours={badge.colours.join(" ")}
      data-stale={stale ? "true" : "false"}
      title={badge.description}
      role="status"
      aria-label={`Robot state ${badge.name}${stale ? " (stale)" : ""}: ${badge.description}`}
    >
      {badge.name.split("_").map((part, i) => (
        // A line may break after an underscore (long names on narrow screens), never inside a word.
        <Fragment key={i}>
          {i > 0 && "_"}
          {i > 0 && <wbr />}
          {part}
        </Fragment>
      ))}
    </div>
  );
}
