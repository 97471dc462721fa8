/**
 * Which robot the panel shows: a choice of the service's robots (each with its link state), and
 * links to the fleet overview and to this robot's kiosk. Choosing changes the URL (`?robot=`),
 * so the browser's back button and a copied link return to the same robot.
 */
import type { FleetTile } from "../lib/fleet";
import { FLEET_HREF, kioskHref } from "../lib/route";

interface Props {
  readonly robot: string;
  /** The service's robots (polled); empty until it has said. */
  readonly robots: readonly FleetTile[];
  readonly onSelect: (robot: string) => void;
}

export function RobotSwitcher({ robot, robots, onSelect }: Props) {
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
            </option>
          ))}
        </select>
      </label>
      <div className="robot-switcher__links">
        <a href={FLEET_HREF} data-testid="fleet-link">
          Fleet
        </a>
        <a href={kioskHref(robot)} data-testid="kiosk-link">
          Kiosk
        </a>
      </div>
    </div>
  );
}
