/**
 * The TCP readout: pose (position, orientation), velocity (linear, angular), external force
 * and moment, three elements each, units beside each quantity; cells written by `useLiveCells`
 * at the stream's own rate.
 */
import { memo } from "react";
import { NO_VALUE, TCP_ROWS, type ReadoutCell } from "../lib/layout/readouts";
import { CELL_ATTRIBUTE, useLiveCells } from "./LiveCells";

const CAPTION = "TCP values of the newest frame (base frame)";
const ELEMENTS = 3;

const CELLS: readonly ReadoutCell[] = TCP_ROWS.flatMap((row) =>
  Array.from({ length: ELEMENTS }, (_, index) => ({ field: row.field, index, decimals: row.decimals })),
);

/** Memoised: the panel re-renders on each snapshot; the readout only when it turns stale or live. */
export const TcpReadout = memo(function TcpReadout({ stale }: { readonly stale: boolean }) {
  const root = useLiveCells<HTMLTableElement>(CELLS);
  return (
    <div className="readout-scroll" role="region" aria-label={CAPTION} tabIndex={0}>
      <table className={`readout tcp-readout${stale ? " is-stale" : ""}`} data-testid="tcp-readout" ref={root}>
        <caption className="visually-hidden">{CAPTION}</caption>
        <tbody>
          {TCP_ROWS.map((row, r) => (
            <tr key={row.field} data-field={row.field}>
              <th scope="row">
                {row.title}
                {row.unit !== "" && <span className="readout__unit"> [{row.unit}]</span>}
              </th>
              {row.channels.slice(0, ELEMENTS).map((element, i) => (
                <td key={element} data-field={row.field} data-index={i}>
                  <span className="readout__element">{element}</span>{" "}
                  <span className="readout__value" {...{ [CELL_ATTRIBUTE]: r * ELEMENTS + i }}>
                    {NO_VALUE}
                  </span>
                </td>
              ))}
            </tr>
          ))}
        </tbody>
      </table>
    </div>
  );
});
