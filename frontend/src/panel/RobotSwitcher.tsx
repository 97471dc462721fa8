/**
 * Which robot the panel shows: a choice of the service's robots (each with its link state), and
 * links to the fleet overview, to this robot's kiosk and to its health page. Choosing changes the URL (`?robot=`),
 * so the browser's back button and a copied link return to the same robot. Another robot with
 * an annunciated alarm is marked (in its option and by a mark beside the choice that opens its
 * panel), from the stream's `cell_alarms`.
 */
import { alarmPaint } from "../lib/alarms/alarms";
import { briefWords, summaryCountWords } from "../lib/alarms/alarmsCell";
import type { FleetTile } from "../lib/fleet/fleet";
import type { AlarmSummary } from "../lib/api/protocol";
import { FLEET_HREF, healthHref, kioskHref } from "../lib/common/route";

interface Props {
  readonly robot: string;
  /** The service's robots (polled); empty until it has said. */
  readonly robots: readonly FleetTile[];
  readonly onSelect: (robot: string) => void;
  /** The robots with annunciated alarms (lib/alarms/alarmsCell.ts alarmsByRobot). */
  readonly alarms?: ReadonlyMap<string, AlarmSummary>;
}

function AlarmMark({ summary, onSelect }: { readonly summary: AlarmSummary; readonly onSelect: (robot: string) => void }) {
  const robot = summary.robot ?? "?";
  const paint = alarmPaint(summary.top?.colour ?? "");
  const words = summary.top != null ? briefWords(summary.top) : summaryCountWords(summary);
  return (
    <button
      type="button"
      className="robot-alarm-mark"
      data-testid="robot-alarm-mark"
      data-robot={robot}
      data-priority={summary.highest_priority ?? ""}
      style={{ background: paint.background, color: paint.text }}
      title={`${robot}: ${words} (${summaryCountWords(summary)}). Show its panel.`}
      onClick={() => onSelect(robot)}
    >
      <span aria-hidden="true">▲</span> {robot}: {summary.highest_priority ?? "alarm"}
    </button>
  );
}

export function RobotSwitcher({ robot, robots, onSelect, alarms }: Props) {
  const marked = [...(alarms?.values() ?? [])].filter((s) => s.robot !== robot);
  // Until the list is known the current robot is the only choice (its name came from the URL).
  const choices = robots;
  const listed = choices.some((r) => r.name === robot);
  return (
    <div className="robot-switcher">
      <label>
        <span className="robot-switcher__label">robot</span>{" "}
        <select data-testid="robot-select" value={robot} onChange={(e) => onSelect(e.target.value)}>
          {!listed && <option value={robot}>{robot}</option>}
          {choices.map((r) => (
            <option key={r.name} value={r.name} data-connection={r.link}>
              {r.name}
              {r.model !== null ? ` · ${r.model}` : ""}
              {r.link !== "connected" ? ` (${r.link})` : ""}
              {r.name !== robot && alarms?.has(r.name) === true ? ` · alarm: ${alarms.get(r.name)?.highest_priority ?? "?"}` : ""}
            </option>
          ))}
        </select>
      </label>
      {marked.length > 0 && (
        <div className="robot-switcher__marks">
          {marked.map((summary) => (
            <AlarmMark key={summary.robot} summary={summary} onSelect={onSelect} />
          ))}
        </div>
      )}
      <div className="robot-switcher__links">
        <a href={FLEET_HREF} data-testid="fleet-link">
          Fleet
        </a>
        <a href={kioskHref(robot)} data-testid="kiosk-link">
          Kiosk
        </a>
        <a href={healthHref(robot)} data-testid="health-link">
          Health
        </a>
      </div>
    </div>
  );
}
