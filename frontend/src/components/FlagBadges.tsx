/** The five status flags with their full names from the layout. */
import type { Frame } from "../generated/layout";
import { FLAG_FIELDS, isFlagField, kebab } from "../lib/layoutInfo";

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
            title={`${field.description} (${field.flag?.abbreviation ?? ""})`}
          >
            <span className="flag__light" aria-hidden="true" />
            <span className="flag__name">{field.flag?.full_name ?? field.name}</span>
            <span className="visually-hidden">{state}</span>
          </div>
        );
      })}
    </div>
  );
}
