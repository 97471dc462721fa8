/**
 * The kiosk's large numeric tiles (chosen in the URL, lib/kiosk/kioskTiles.ts), its clock and the
 * state in plain words. Read-only: numbers and words, nothing to press. The tiles' arrangement
 * and text sizes come from lib/kiosk/kioskLayout.ts's `tileGrid` for the room the kiosk gives them.
 */
import { memo, useEffect, useState, type CSSProperties } from "react";
import type { FieldInfo, Frame } from "../generated/layout";
import { formatClock } from "../lib/common/dates";
import type { TileGrid } from "../lib/kiosk/kioskLayout";
import { kebab } from "../lib/layout/layoutInfo";
import { stateWords, tileCells } from "../lib/kiosk/kioskTiles";
import "../styles/kioskTiles.css";

export const KioskTile = memo(function KioskTile({ field, frame, cellColumns }: { field: FieldInfo; frame: Frame | null; cellColumns: number }) {
  const cells = tileCells(field, frame);
  const style = { "--cell-columns": Math.max(1, Math.min(cellColumns, cells.length)) } as CSSProperties;
  return (
    <section className="tile" data-testid={`tile-${kebab(field.name)}`} aria-label={field.description}>
      <h2 className="tile__title">
        {field.description}
        {field.unit !== "" && <span className="tile__unit"> [{field.unit}]</span>}
      </h2>
      <dl className="tile__cells" style={style}>
        {cells.map((cell, i) => (
          <div key={cell.label} className="tile__cell">
            <dt>
              {cell.label}
              {/* On the label's line: the value keeps the width the layout gave it. */}
              {cell.slow === true && (
                <span className="tile__slow" data-testid="tile-cycle-slow" title="over a tenth slower than the mean of the last ten">
                  {" "}
                  ▲ slow
                </span>
              )}
            </dt>
            <dd data-testid={`tile-${kebab(field.name)}-${i}`} data-slow={cell.slow === true ? "true" : undefined}>
              {cell.text}
            </dd>
          </div>
        ))}
      </dl>
    </section>
  );
});

interface TilesProps {
  readonly fields: readonly FieldInfo[];
  readonly unknown: readonly string[];
  readonly frame: Frame | null;
  /** Arrangement and sizes (null until the kiosk has measured its room). */
  readonly grid: TileGrid | null;
}

export function KioskTiles({ fields, unknown, frame, grid }: TilesProps) {
  const style = (
    grid === null
      ? {}
      : {
          "--tile-columns": grid.columns,
          "--tile-value": `${grid.value_px}px`,
          "--tile-label": `${grid.label_px}px`,
          "--tile-title": `${grid.title_px}px`,
        }
  ) as CSSProperties;
  return (
    <div
      className={`kiosk__tiles${grid?.stacked === true ? " kiosk__tiles--stacked" : ""}`}
      data-testid="kiosk-tiles"
      data-value-px={grid?.value_px ?? ""}
      style={style}
    >
      {fields.map((field) => (
        <KioskTile key={field.name} field={field} frame={frame} cellColumns={grid?.cellColumns ?? 3} />
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

/** The site's time of day, to the second (24 h, as every time on the pages). */
export function KioskClock() {
  const [now, setNow] = useState(() => Date.now());
  useEffect(() => {
    const timer = setInterval(() => setNow(Date.now()), 1000);
    return () => clearInterval(timer);
  }, []);
  return (
    <time className="kiosk__clock" data-testid="kiosk-clock" dateTime={new Date(now).toISOString()}>
      {formatClock(now)}
    </time>
  );
}
