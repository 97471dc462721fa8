/**
 * The joint table: position, velocity, motor current, motor temperature, torque and external
 * torque of the six joints, units in the header, following the stream at its own rate (the
 * cells are written by `useLiveCells`, not by React renders).
 */
import { memo } from "react";
import { JOINT_COLUMNS, NO_VALUE, headerWithUnit, type ReadoutCell } from "../lib/layout/readouts";
import { CELL_ATTRIBUTE, useLiveCells } from "./LiveCells";

const CAPTION = "Joint values of the newest frame";
const JOINT_COUNT = JOINT_COLUMNS[0]?.channels.length ?? 0;
const JOINT_LABELS = JOINT_COLUMNS[0]?.channels ?? [];

/** Row-major: joint j, column c is cell j * columns + c. */
const CELLS: readonly ReadoutCell[] = Array.from({ length: JOINT_COUNT }, (_, joint) =>
  JOINT_COLUMNS.map((c) => ({ field: c.field, index: joint, decimals: c.decimals })),
).flat();

/** Memoised: the panel re-renders on each snapshot; the table only when it turns stale or live. */
export const JointTable = memo(function JointTable({ stale }: { readonly stale: boolean }) {
  const root = useLiveCells<HTMLTableElement>(CELLS);
  return (
    <div className="readout-scroll" role="region" aria-label={CAPTION} tabIndex={0}>
      <table className={`readout joint-table${stale ? " is-stale" : ""}`} data-testid="joint-table" ref={root}>
        <caption className="visually-hidden">{CAPTION}</caption>
        <thead>
          <tr>
            <th scope="col">Joint</th>
            {JOINT_COLUMNS.map((c) => (
              <th key={c.field} scope="col" data-field={c.field}>
                {c.title}
                {c.unit !== "" && <span className="readout__unit"> [{c.unit}]</span>}
              </th>
            ))}
          </tr>
        </thead>
        <tbody>
          {JOINT_LABELS.map((label, joint) => (
            <tr key={label} data-joint={joint}>
              <th scope="row">{label}</th>
              {JOINT_COLUMNS.map((c, col) => (
                <td
                  key={c.field}
                  {...{ [CELL_ATTRIBUTE]: joint * JOINT_COLUMNS.length + col }}
                  data-field={c.field}
                  title={`${label} ${headerWithUnit(c)}`}
                >
                  {NO_VALUE}
                </td>
              ))}
            </tr>
          ))}
        </tbody>
      </table>
    </div>
  );
});
