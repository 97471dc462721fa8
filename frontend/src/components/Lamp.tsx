/** A read-only lamp: on, off, or unknown (no frame yet). */
import { memo } from "react";

interface Props {
  readonly testId: string;
  readonly label: string;
  readonly on: boolean | null | undefined;
  readonly title?: string;
  /** The point's tag name, shown under its label. */
  readonly tag?: string | undefined;
  readonly variant?: "io" | "flag" | "register";
}

export const Lamp = memo(function Lamp({ testId, label, on, title, tag, variant = "io" }: Props) {
  const state = on === true ? "on" : "off";
  return (
    <div
      className={`lamp lamp--${variant}${on === null || on === undefined ? " lamp--unknown" : ""}`}
      data-testid={testId}
      data-state={state}
      title={title ?? label}
    >
      <span className="lamp__light" aria-hidden="true" />
      <span className="lamp__label">{label}</span>
      {tag !== undefined && tag !== "" && (
        <span className="lamp__tag" data-testid={`${testId}-tag`}>
          {tag}
        </span>
      )}
      <span className="visually-hidden">{state}</span>
    </div>
  );
});
