/**
 * The knocks of this shift on the arm's joint-space picture (lib/health/knocks.ts: an axis per
 * joint over its range, each knock a line through the positions the arm had), with the same
 * knocks as a table for reading and for a screen reader, and this shift's counts in words.
 */
import { ARMS, DEFAULT_ARM, type ArmName } from "../generated/arms";
import { formatTimestamp } from "../lib/common/dates";
import type { Knocks } from "../lib/health/healthTypes";
import { KNOCK_KINDS, knockCountsWords, knockPicture, knockWords } from "../lib/health/knocks";

function limitsOf(arm: string | null | undefined): number[] {
  const known = arm !== null && arm !== undefined && arm in ARMS ? (arm as ArmName) : DEFAULT_ARM;
  return ARMS[known].joints.map((j) => j.limit_deg);
}

export function KnocksView({ knocks, arm }: { readonly knocks: Knocks | null | undefined; readonly arm: string | null | undefined }) {
  const events = [...(knocks?.events ?? [])].sort((a, b) => b.time - a.time);
  const picture = knockPicture(events, limitsOf(arm));
  const kinds = Object.entries(KNOCK_KINDS);
  return (
    <div className="health-knocks">
      <p data-testid="health-knock-counts">
        This shift{typeof knocks?.shift_start === "number" ? ` (since ${formatTimestamp(knocks.shift_start)})` : ""}: {knockCountsWords(knocks)}
      </p>
      <svg
        className="health-knocks__picture"
        viewBox={`0 0 ${picture.width} ${picture.height}`}
        role="img"
        aria-labelledby="health-knocks-title health-knocks-desc"
        data-testid="health-knocks-picture"
        data-knocks={events.length}
      >
        <title id="health-knocks-title">Where in joint space the knocks happened</title>
        <desc id="health-knocks-desc">
          One vertical axis per joint, from its lowest position at the bottom to its highest at the top; each knock is a line through the arm's six joint
          positions when it happened. {events.length === 0 ? "No knock this shift." : `${events.length} knock${events.length === 1 ? "" : "s"}, listed in the table below.`}
        </desc>
        {picture.axes.map((axis) => (
          <g key={axis.joint} className="health-knocks__axis">
            <line x1={axis.x} x2={axis.x} y1={picture.top} y2={picture.bottom} />
            <text x={axis.x} y={picture.top - 8} textAnchor="middle">
              +{axis.limit_deg}°
            </text>
            <text x={axis.x} y={picture.bottom + 14} textAnchor="middle">
              −{axis.limit_deg}°
            </text>
            <text x={axis.x} y={picture.bottom + 26} textAnchor="middle" className="health-knocks__joint">
              J{axis.joint}
            </text>
          </g>
        ))}
        <line className="health-knocks__zero" x1={picture.axes[0]?.x ?? 0} x2={picture.axes[picture.axes.length - 1]?.x ?? 0} y1={(picture.top + picture.bottom) / 2} y2={(picture.top + picture.bottom) / 2} />
        {picture.lines.map((line, i) => (
          <polyline
            key={`${line.event.time}-${i}`}
            points={line.points}
            fill="none"
            stroke={line.colour}
            strokeWidth={2}
            strokeDasharray={line.dash === "" ? undefined : line.dash}
            data-kind={line.event.kind}
          >
            <title>{`${formatTimestamp(line.event.time)}: ${knockWords(line.event)}`}</title>
          </polyline>
        ))}
      </svg>
      <ul className="health-knocks__legend" aria-label="kinds of knock">
        {kinds.map(([kind, style]) => (
          <li key={kind}>
            <svg width="28" height="10" aria-hidden="true">
              <line x1="0" x2="28" y1="5" y2="5" stroke={style.colour} strokeWidth={2} strokeDasharray={style.dash === "" ? undefined : style.dash} />
            </svg>{" "}
            {style.words}
          </li>
        ))}
      </ul>
      {events.length > 0 && (
        <div className="table-scroll" tabIndex={0} role="region" aria-label="knocks of this shift">
          <table data-testid="health-knocks-table">
            <caption>Knocks of this shift, newest first</caption>
            <thead>
              <tr>
                <th scope="col">when</th>
                <th scope="col">what</th>
                <th scope="col">joint positions (°, J1–J6)</th>
              </tr>
            </thead>
            <tbody>
              {events.map((event, i) => (
                <tr key={`${event.time}-${i}`} data-testid="health-knock-row" data-kind={event.kind} data-joint={event.joint ?? ""}>
                  <td className="nowrap">{formatTimestamp(event.time)}</td>
                  <td>{knockWords(event)}</td>
                  <td className="nowrap">{event.joint_position_deg.map((q) => q.toFixed(1)).join(", ")}</td>
                </tr>
              ))}
            </tbody>
          </table>
        </div>
      )}
    </div>
  );
}
