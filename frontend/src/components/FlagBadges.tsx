/**
 * The five status flags in plain words from the layout ("Servo on"); the robot's own name of the
 * flag (SERVO_ON_ROBOT, SO) in the tooltip.
 */
import type { Frame } from "../generated/layout";
import { FLAG_FIELDS, flagEnumName, isFlagField, kebab } from "../lib/layout/layoutInfo";

interface Props {
  readonly frame: Frame | null;
  readonly stale: boolean;
}

export function FlagBadges({ frame, stale }: Props) {
  return (
    <div className={`flags${stale ? " is-stale" : ""}`} aria-label="Robot flags">
      {FLAG_FIELDS.map((field) => {
        const on = frame !== null && isFlagField(field.name) ? frame[field.name] : null;
        const state = on === true ? "on" : "off";
        return (
          <div
            key={field.name}
            className={`flag flag--${kebab(field.name)}${on === null ? " flag--unknown" : ""}`}
            data-testid={`flag-${kebab(field.name)}`}
            data-state={state}
            title={`${field.description}: ${on === null ? "unknown" : state} (${flagEnumName(field)})`}
          >
            <span className="flag__light" aria-hidden="true" />
            <span className="flag__name">{field.description}</span>
            <span className="visually-hidden">{state}</span>
          </div>
        );
      })}
    </div>
  );
}
