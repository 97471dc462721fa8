/**
 * The fleet overview (`/fleet`): one tile per robot of the service with its state, its link
 * (its newest frame's age, stale or not, the frames lost), who holds its control, its alarms
 * (the most urgent in words, the counts), its health (the worst verdict of its joints, linked to
 * its health page) and links to its panel and its kiosk. The tiles share the screen's width
 * (styles/fleet.css). Read only: it polls `GET /api/v1/robots` once a second (lib/fleet/fleet.ts)
 * and each robot's health every few seconds (lib/health/fleetHealth.ts), and writes nothing.
 */
import { useEffect, useMemo, useSyncExternalStore } from "react";
import { StateBadge } from "../components/StateBadge";
import { api } from "../lib/api/api";
import { alarmPaint } from "../lib/alarms/alarms";
import { healthHref } from "../lib/common/route";
import { FleetPoller, type FleetTile } from "../lib/fleet/fleet";
import { healthApi } from "../lib/health/healthApi";
import { FleetHealthPoller, type RobotHealthCell } from "../lib/health/fleetHealth";
import { verdictPaint } from "../lib/health/verdicts";
import "../styles/fleet.css";

/** The tile's health: the worst verdict in words on its colour, linked to the robot's health page. */
function HealthFact({ cell }: { cell: RobotHealthCell | undefined }) {
  const paint = cell?.verdict != null ? verdictPaint(cell.verdict) : null;
  return (
    <div>
      <dt>health</dt>
      <dd data-testid="fleet-health" data-verdict={cell?.verdict ?? ""} data-maintenance-due={cell?.maintenanceDue === true ? "true" : "false"}>
        {cell === undefined ? (
          "asking…"
        ) : (
          <a
            href={cell.href}
            data-testid="fleet-health-link"
            className={paint !== null ? "fleet-tile__verdict" : undefined}
            style={paint !== null ? { background: paint.background, color: paint.text } : undefined}
          >
            {cell.words}
          </a>
        )}
      </dd>
    </div>
  );
}

function Tile({ tile, stale, health }: { tile: FleetTile; stale: boolean; health: RobotHealthCell | undefined }) {
  const live = tile.link === "connected" && !stale;
  return (
    <article className={`fleet-tile${live ? "" : " is-stale"}`} data-testid="fleet-tile" data-robot={tile.name} data-link={tile.link}>
      <header className="fleet-tile__header">
        <h2>
          <a href={tile.panelHref} data-testid="fleet-panel-link">
            {tile.name}
          </a>
        </h2>
        <span className="fleet-tile__robot" data-testid="fleet-model">
          {tile.model ?? "model not yet known"} · {tile.host}
          {tile.readOnly ? " · read-only (input only)" : ""}
        </span>
      </header>
      <StateBadge value={tile.stateValue} stale={!live} size="panel" />
      <dl className="fleet-tile__facts">
        <div>
          <dt>link</dt>
          <dd className={`health--${live ? "connected" : "disconnected"}`} data-testid="fleet-connection" data-state={tile.link}>
            <span className="health__dot" aria-hidden="true" /> {tile.linkWords}
          </dd>
        </div>
        <div>
          <dt>control</dt>
          <dd data-testid="fleet-holder" data-holder={tile.holder ?? ""}>
            {tile.holder ?? "nobody"}
          </dd>
        </div>
        <div>
          <dt>newest frame</dt>
          <dd data-testid="fleet-frame-age" data-stale={tile.stale ? "true" : "false"}>
            {tile.frameAgeWords}
            {tile.stale && (
              <span className="fleet-tile__stale" data-testid="fleet-stale">
                stale
              </span>
            )}
          </dd>
        </div>
        <div>
          <dt>frames lost (gaps)</dt>
          <dd data-testid="fleet-gaps" data-gaps-per-min={tile.gapsPerMin ?? ""} data-gaps={tile.gaps ?? ""}>
            {tile.gapsWords}
          </dd>
        </div>
        <HealthFact cell={health} />
        {tile.alarms !== null && (
          <div className="fleet-tile__alarms">
            <dt>alarms</dt>
            <dd
              data-testid="fleet-alarms"
              data-active={tile.alarms.active}
              data-annunciated={tile.alarms.annunciated ?? 0}
              data-unacknowledged={tile.alarms.unacknowledged}
              data-priority={tile.alarms.highest_priority ?? ""}
            >
              {tile.topAlarmWords !== null && tile.alarms.top != null && (
                <span
                  className="fleet-tile__top-alarm"
                  data-testid="fleet-top-alarm"
                  style={{ background: alarmPaint(tile.alarms.top.colour).background, color: alarmPaint(tile.alarms.top.colour).text }}
                >
                  {tile.topAlarmWords}
                </span>
              )}
              <span data-testid="fleet-alarm-counts">{tile.alarmWords}</span>
            </dd>
          </div>
        )}
      </dl>
      {/* One navigation landmark per tile: each named by its robot (axe's landmark-unique). */}
      <nav className="fleet-tile__links" aria-label={`${tile.name}: its pages`}>
        <a href={tile.panelHref}>Panel</a>
        <a href={tile.kioskHref} data-testid="fleet-kiosk-link">
          Kiosk
        </a>
        <a href={healthHref(tile.name)}>Health</a>
      </nav>
    </article>
  );
}

export function FleetApp() {
  const poller = useMemo(() => new FleetPoller(() => api.robots()), []);
  useEffect(() => {
    poller.start();
    return () => poller.stop();
  }, [poller]);
  const fleet = useSyncExternalStore(poller.subscribe, poller.getSnapshot);
  const healthPoller = useMemo(() => new FleetHealthPoller((robot) => healthApi.report(robot)), []);
  useEffect(() => {
    healthPoller.start();
    return () => healthPoller.stop();
  }, [healthPoller]);
  const names = fleet.tiles.map((t) => t.name).join("\n");
  useEffect(() => healthPoller.setRobots(names === "" ? [] : names.split("\n")), [healthPoller, names]);
  const health = useSyncExternalStore(healthPoller.subscribe, healthPoller.getSnapshot);
  return (
    <div className="fleet" data-testid="fleet">
      <header className="fleet__header">
        <h1>Fleet</h1>
        <span className="fleet__count">
          {fleet.loaded ? `${fleet.tiles.length} robot${fleet.tiles.length === 1 ? "" : "s"}` : "asking the service…"}
        </span>
      </header>
      {fleet.error !== null && (
        <div className="stale-banner" role="alert" data-testid="fleet-error">
          {fleet.stale ? "Not current: " : ""}the service did not answer with its robots: {fleet.error}
        </div>
      )}
      <main className="fleet__tiles">
        {fleet.tiles.map((tile) => (
          <Tile key={tile.name} tile={tile} stale={fleet.stale} health={health.get(tile.name)} />
        ))}
      </main>
    </div>
  );
}
