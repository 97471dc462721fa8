/**
 * Layer: React glue for numeric readouts that follow the stream.
 *
 * React renders a readout's table once; on every beat of the page's plot coordinator (10 times a
 * second, the monitoring values' rate, in the animation frame the plots are drawn in) the newest
 * frame's numbers are written straight into the cells whose text changed (architecture rule:
 * samples never pass through React state, so a 100 Hz stream costs no React render; and the
 * page's picture changes ten times a second, not in every frame). Read-only.
 */
import { useEffect, useRef, type RefObject } from "react";
import { updateTexts, type ReadoutCell } from "../lib/layout/readouts";
import { useRuntime } from "./runtimeContext";

/** The attribute naming a cell's position in `cells`; put it on every value element. */
export const CELL_ATTRIBUTE = "data-cell";

/**
 * Keep the elements marked `data-cell="i"` under the returned ref showing `cells[i]` of the
 * newest frame. Each element also carries the raw value in `data-value` (tests, copy and paste).
 */
export function useLiveCells<E extends HTMLElement>(cells: readonly ReadoutCell[]): RefObject<E | null> {
  const { live, coordinator } = useRuntime();
  const root = useRef<E | null>(null);
  useEffect(() => {
    const container = root.current;
    if (container === null) return;
    const elements: (HTMLElement | undefined)[] = [];
    for (const el of container.querySelectorAll<HTMLElement>(`[${CELL_ATTRIBUTE}]`)) {
      elements[Number(el.getAttribute(CELL_ATTRIBUTE))] = el;
    }
    const texts: string[] = cells.map(() => "");
    const changed: number[] = cells.map(() => 0);
    let seen = -1;
    const write = () => {
      const received = live.framesReceived;
      if (received === seen) return;
      seen = received;
      const frame = live.latestFrame();
      const count = updateTexts(frame, cells, texts, changed);
      for (let k = 0; k < count; k++) {
        const i = changed[k] ?? 0;
        const el = elements[i];
        const cell = cells[i];
        if (el === undefined || cell === undefined) continue;
        el.textContent = texts[i] ?? "";
        const value = frame?.[cell.field][cell.index];
        el.dataset.value = value === null || value === undefined ? "" : String(value);
      }
      container.dataset.frames = String(received);
    };
    write();
    return coordinator.onBeat(write);
  }, [live, coordinator, cells]);
  return root;
}
