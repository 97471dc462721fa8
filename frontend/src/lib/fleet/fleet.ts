/**
 * Layer: the fleet overview's data (plain TypeScript, no React, no DOM): one tile per robot
 * from `GET /api/v1/robots`, polled, with the last good answer kept and marked stale when the
 * service stops answering. Names of robot states come from the generated layout (the tile's
 * state badge); this module only decides what each tile says.
 */
import { briefWords, summaryCountWords } from "../alarms/alarmsCell";
import { formatDuration_ms } from "../stream/health";
import type { AlarmSummary, LinkState, RobotSummary } from "../api/protocol";
import { Poller, type Fetched, type PolledSnapshot } from "../common/poller";
import { kioskHref, panelHref } from "../common/route";

export interface FleetTile {
  readonly name: string;
  readonly host: string;
  /** The robot's model when the service knows it (from its identity), else null. */
  readonly model: string | null;
  readonly readOnly: boolean;
  /** The robot link's state, and in words with its reason. */
  readonly link: LinkState;
  readonly linkWords: string;
  /** The robot-state value of the newest frame (the badge names it), null without one. */
  readonly stateValue: number | null;
  /** Who holds control of this robot's outputs, null: nobody. */
  readonly holder: string | null;
  /** Its alarms at a glance (null: the service does not report alarms). */
  readonly alarms: AlarmSummary | null;
  /** Its alarms' counts in words ("2 alarms (1 unacknowledged)", "none"). */
  readonly alarmWords: string;
  /** Its most urgent annunciated alarm in words, null: none. */
  readonly topAlarmWords: string | null;
  /** How old its newest frame is ("12 ms", "no frame yet") and whether that is too old. */
  readonly frameAgeWords: string;
  readonly stale: boolean;
  /** T→O sequence gaps: in the last minute and on the current connection (null: not connected). */
  readonly gapsPerMin: number | null;
  readonly gaps: number | null;
  readonly gapsWords: string;
  readonly panelHref: string;
  readonly kioskHref: string;
}

export function fleetTile(robot: RobotSummary): FleetTile {
  const link = robot.connection;
  const reason = robot.connection_reason;
  return {
    name: robot.name,
    host: robot.host,
    model: robot.model,
    readOnly: robot.mode === "input_only",
    link,
    linkWords: reason !== null && reason !== "" && link !== "connected" ? `${link}: ${reason}` : link,
    // A state from a link that is down is history: the badge shows NO DATA rather than a stale state.
    stateValue: link === "connected" ? robot.robot_state : null,
    holder: robot.holder?.user ?? null,
    alarms: robot.alarms ?? null,
    alarmWords: alarmWords(robot.alarms ?? null),
    topAlarmWords: robot.alarms?.top != null ? briefWords(robot.alarms.top) : null,
    frameAgeWords: robot.frame_age_s === null || robot.frame_age_s === undefined ? "no frame yet" : formatDuration_ms(robot.frame_age_s * 1000),
    stale: robot.stale ?? link !== "connected",
    gapsPerMin: robot.gaps_per_min ?? null,
    gaps: robot.gaps ?? null,
    gapsWords: gapsWords(robot.gaps_per_min ?? null, robot.gaps ?? null),
    panelHref: panelHref(robot.name),
    kioskHref: kioskHref(robot.name),
  };
}

/** "none", "2 alarms (1 unacknowledged), 1 shelved", "—" when the service does not say. */
export function alarmWords(alarms: AlarmSummary | null): string {
  return alarms === null ? "—" : summaryCountWords(alarms);
}

/** "3 in the last minute (12 on this connection)", "none in the last minute", "not connected". */
export function gapsWords(perMin: number | null, total: number | null): string {
  if (perMin === null && total === null) return "not connected";
  const minute = perMin === null ? "? in the last minute" : perMin === 0 ? "none in the last minute" : `${perMin} in the last minute`;
  return total !== null ? `${minute} (${total} on this connection)` : minute;
}

/** What fetching the list gave: the robots, or why there are none. */
export type RobotsAnswer =
  | { readonly ok: true; readonly robots: readonly RobotSummary[] }
  | { readonly ok: false; readonly reason: string };

export interface FleetSnapshot {
  /** The tiles of the last good answer (empty before the first one). */
  readonly tiles: readonly FleetTile[];
  /** Why the last poll failed, null when it succeeded. */
  readonly error: string | null;
  /** The last good answer is older than the newest poll: tiles show what was, not what is. */
  readonly stale: boolean;
  /** A first answer (good or bad) has come. */
  readonly loaded: boolean;
  /** A good answer has come: `tiles` is the service's list (else: not known yet). */
  readonly answered: boolean;
}

/** The names of the service's robots, in its order; null until it has said. */
export function knownRobots(fleet: FleetSnapshot): readonly string[] | null {
  return fleet.answered ? fleet.tiles.map((t) => t.name) : null;
}

export const FLEET_POLL_MS = 1000;

/**
 * Polls `fetchRobots` every `interval_ms` (lib/common/poller.ts: one request at a time, the last
 * good list kept and marked stale) and publishes the tiles to its subscribers.
 */
export class FleetPoller {
  private readonly poller: Poller<readonly FleetTile[]>;
  private shown: PolledSnapshot<readonly FleetTile[]> | null = null;
  private current: FleetSnapshot = { tiles: [], error: null, stale: false, loaded: false, answered: false };

  constructor(fetchRobots: () => Promise<RobotsAnswer>, interval_ms = FLEET_POLL_MS) {
    this.poller = new Poller(async (): Promise<Fetched<readonly FleetTile[]>> => {
      const answer = await fetchRobots();
      return answer.ok ? { ok: true, value: answer.robots.map(fleetTile) } : { ok: false, status: 0, reason: answer.reason };
    }, interval_ms);
  }

  subscribe = (listener: () => void): (() => void) => this.poller.subscribe(listener);

  /** The same object until the next answer (useSyncExternalStore compares by identity). */
  getSnapshot = (): FleetSnapshot => {
    const polled = this.poller.getSnapshot();
    if (polled !== this.shown) {
      this.shown = polled;
      this.current = { tiles: polled.value ?? [], error: polled.error, stale: polled.stale, loaded: polled.loaded, answered: polled.value !== null };
    }
    return this.current;
  };

  start(): void {
    this.poller.start();
  }

  stop(): void {
    this.poller.stop();
  }

  /** Poll now (e.g. after a login) instead of waiting for the next turn. */
  refresh(): void {
    this.poller.refresh();
  }
}
