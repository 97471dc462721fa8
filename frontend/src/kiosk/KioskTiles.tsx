/**
 * The kiosk's large numeric tiles (chosen in the URL, lib/kioskTiles.ts), its clock and the
 * state in plain words. Read-only: numbers and words, nothing to press.
 */
import { memo, useEffect, useState } from "react";
import type { FieldInfo, Frame } from "../generated/layout";
import { kebab } from "../lib/layoutInfo";
import { stateWords, tileCells } from "../lib/kioskTiles";
import "../styles/kioskTiles.css";

export const KioskTile = memo(function KioskTile({ field, frame }: { field: FieldInfo; frame: Frame | null }) {
  const cells = tileCells(field, frame);
  return (
    <section className="tile" data-testid={`tile-${kebab(field.name)}`} aria-label={field.description}>
      <h2 className="tile__title">
        {field.description}
        {field.unit !== "" && <span className="tile__unit"> [{field.unit}]</span>}
      </h2>
      <dl className={`tile__cells tile__cells--${Math.min(cells.length, 6)}`}>
        {cells.map((cell, i) => (
          <div key={cell.label} className="tile__cell">
            <dt>{cell.label}</dt>
            <dd data-testid={`tile-${kebab(field.name)}-${i}`}>{cell.text}</dd>
          </div>
        ))}
      </dl>
    </section>
  );
});

export function KioskTiles({ fields, unknown, frame }: { fields: readonly FieldInfo[]; unknown: readonly string[]; frame: Frame | null }) {
  return (
    <div className="kiosk__tiles" data-testid="kiosk-tiles">
      {fields.map((field) => (
        <KioskTile key={field.name} field={field} frame={frame} />
      ))}
      {unknown.length > 0 && (
        <p className="tile__unknown" data-testid="tile-unknown">
          Not a number this robot reports: {unknown.join(", ")}
        </p>
      )}
    </div>
  );
}

/** What the state means, from the layout (the badge above it says the state in plain words). */
export function KioskStateWords({ value }: { value: number | null | undefined }) {
  const words = stateWords(value);
  return (
    <div className="kiosk__state-words" data-testid="kiosk-state-words" data-state-title={words.title}>
      <span className="kiosk__state-detail">{words.detail}</span>
    </div>
  );
}

/** Local time, to the second. */
export function KioskClock() {
  const [now, setNow] = useState(() => new Date());
  useEffect(() => {
    const timer = setInterval(() => setNow(new Date()), 1000);
    return () => clearInterval(timer);
  }, []);
  return (
    <time className="kiosk__clock" data-testid="kiosk-clock" dateTime={now.toISOString()}>
      {now.toLocaleTimeString([], { hour: "2-digit", minute: "2-digit", second: "2-digit" })}
    </time>
  );
}
