/**
 * Layer: the plant page's data (plain TypeScript, no React, no DOM): what `cobot-hmi plant`
 * answers (`/api/v1/plant/nodes`, `/alarms`, `/shifts`; types generated from its OpenAPI
 * document, docs/plant-openapi.json) turned into what the page shows: one card per cell (a
 * Sparkplug edge node) with a row per robot (its state in words with the pendant's colours,
 * its most urgent active alarm, its cycle times, its health verdicts, online or offline since
 * when, its shift), the filters (area: the Sparkplug group; state group), the plant's alarm
 * list and each cell's ISA-18.2 figures in words, and how dense the wall display must be to
 * hold every robot without scrolling.
 */
import type { components } from "../../generated/plantApi";
import { LAYOUT } from "../../generated/layout";
import { PRIORITY_COLOUR, alarmPaint } from "../alarms/alarms";
import { paintOf, stateBadge, UNKNOWN_PAINT, type Paint } from "../layout/stateBadge";
import { formatMoment } from "../common/dates";
import { historyHref } from "../common/route";

type Schemas = components["schemas"];
export type PlantNode = Schemas["NodeModel"];
export type PlantDevice = Schemas["DeviceModel"];
export type PlantAlarms = Schemas["AlarmsAnswer"];
export type PlantTransition = Schemas["AlarmTransitionModel"];
export type CellFigures = Schemas["CellFiguresModel"];
export type PlantShifts = Schemas["ShiftsAnswer"];
export type RobotShift = Schemas["RobotShiftModel"];
export type PlantPeer = Schemas["PeerModel"];

/** The plant's state groups (model.state_group), and a robot whose cell or itself is offline. */
export const STATE_GROUPS = ["running", "standby", "stopped", "error"] as const;
export type StateGroup = (typeof STATE_GROUPS)[number];
export type StateFilter = StateGroup | "offline" | "alarm";
export const STATE_FILTERS: readonly StateFilter[] = [...STATE_GROUPS, "offline", "alarm"];

/** What the page is filtered by; null: everything. */
export interface PlantFilter {
  /** A Sparkplug group (the plant's area). */
  readonly area: string | null;
  readonly state: StateFilter | null;
}

export const NO_FILTER: PlantFilter = { area: null, state: null };

/** A cell's key as the API names it: "group/node" (a node id is unique in its group only). */
export function cellKey(group: string, node: string): string {
  return `${group}/${node}`;
}

// ---------------------------------------------------------------- the robot's state

export interface StateView {
  /** The state in words ("Standalone running"); the layout's label for our cells. */
  readonly words: string;
  /** The layout's name ("STANDALONE_RUNNING"), or the edge node's own words. */
  readonly name: string | null;
  readonly paints: readonly Paint[];
  readonly alternating: boolean;
}

const BY_NAME = new Map<string, number>(LAYOUT.robot_states.map((s) => [s.name, s.value]));

/** "SOME_STATE" → "Some state": a state another edge node names that the layout does not know. */
export function wordsOfName(name: string): string {
  const words = name.replace(/[_-]+/g, " ").trim().toLowerCase();
  return words === "" ? "Unknown state" : words[0]!.toUpperCase() + words.slice(1);
}

/** A device's state in words with the pendant's colours (the cell's badge, from the layout). */
export function stateView(name: string | null | undefined): StateView {
  if (name === null || name === undefined || name === "") {
    return { words: "No state yet", name: null, paints: [UNKNOWN_PAINT], alternating: false };
  }
  const value = BY_NAME.get(name);
  if (value === undefined) return { words: wordsOfName(name), name, paints: [UNKNOWN_PAINT], alternating: false };
  const badge = stateBadge(value);
  return { words: badge.label, name, paints: badge.paints, alternating: badge.alternating };
}

// ---------------------------------------------------------------- words

/** "12.3 s", "—" for none: a cycle time. */
export function secondsWords(s: number | null | undefined): string {
  if (s === null || s === undefined || !Number.isFinite(s)) return "—";
  return s >= 100 ? `${Math.round(s)} s` : `${s.toFixed(1)} s`;
}

/** "4 h 05 min", "12 min", "40 s": a span of time, briefly. */
export function spanWords(s: number): string {
  if (!Number.isFinite(s) || s < 0) return "—";
  if (s < 60) return `${Math.round(s)} s`;
  const minutes = Math.floor(s / 60);
  if (minutes < 60) return `${minutes} min`;
  return `${Math.floor(minutes / 60)} h ${String(minutes % 60).padStart(2, "0")} min`;
}

/** "online since 07:21:04", "offline since 2026-11-26 23:58:10". */
export function sinceWords(online: boolean, since_s: number, now_ms: number, zone?: string): string {
  const when = since_s > 0 ? formatMoment(since_s * 1000, now_ms, zone) : "—";
  return `${online ? "online" : "offline"} since ${when}`;
}

/** A priority's paint: the cell's own colours for alarms (critical red … low blue). */
export function priorityPaint(priority: string): Paint {
  const colour = (PRIORITY_COLOUR as Readonly<Record<string, string>>)[priority];
  return colour === undefined ? paintOf("white") : alarmPaint(colour);
}

/** "2.4 per 10 min", with "flood" when any 10 minutes held more than 10 (ISA-18.2). */
export function figuresWords(figures: CellFigures | undefined): string {
  if (figures === undefined) return "no alarms";
  const rate = figures.alarms_per_10_min;
  const words = `${rate < 10 ? rate.toFixed(1) : Math.round(rate)} per 10 min`;
  return figures.flood ? `FLOOD (${figures.peak_per_10_min} in 10 min) · ${words}` : words;
}

/** The top ten bad actors in words: "m1013 estop ×12". */
export function badActorWords(figures: CellFigures): readonly string[] {
  return figures.bad_actors.map(([device, alarm, count]) => `${device} ${alarm} ×${count}`);
}

// ---------------------------------------------------------------- rows and cells

export interface ShiftView {
  /** Fractions of the shift's known time in each state group, in STATE_GROUPS' order. */
  readonly fractions: readonly number[];
  readonly cycles: number;
  readonly meanCycleWords: string;
  /** "running 3 h 10 min, standby 20 min, …; 412 cycles, mean 12.3 s". */
  readonly words: string;
}

export function shiftView(shift: RobotShift | undefined): ShiftView | null {
  if (shift === undefined) return null;
  const seconds = STATE_GROUPS.map((g) => shift.seconds[g] ?? 0);
  const total = seconds.reduce((a, b) => a + b, 0);
  const spans = STATE_GROUPS.map((g, i) => `${g} ${spanWords(seconds[i]!)}`).join(", ");
  const mean = secondsWords(shift.mean_cycle_s);
  return {
    fractions: seconds.map((s) => (total > 0 ? s / total : 0)),
    cycles: shift.cycles,
    meanCycleWords: mean,
    words: `${spans}; ${shift.cycles} cycle${shift.cycles === 1 ? "" : "s"}, mean ${mean}`,
  };
}

export interface RobotRow {
  readonly key: string;
  readonly group: string;
  readonly node: string;
  readonly device: string;
  /** Online only while its cell is too. */
  readonly online: boolean;
  readonly sinceWords: string;
  readonly state: StateView;
  /** running, standby, stopped, error; null while no state is known. */
  readonly stateGroup: string | null;
  readonly topAlarm: { readonly priority: string; readonly text: string; readonly paint: Paint } | null;
  readonly alarmCount: number;
  readonly cycleLastWords: string;
  readonly cycleAverageWords: string;
  /** "friction ok · reducer watch". */
  readonly healthWords: string | null;
  readonly shift: ShiftView | null;
  /** Its panel in its cell (`HMI/?robot=NAME`), null when the cell names no HMI. */
  readonly panelHref: string | null;
  /** Its recorded frames over the page's range in its cell (`HMI/?robot=NAME&from=&to=`). */
  readonly historyHref: string | null;
}

export interface CellCard {
  readonly key: string;
  readonly group: string;
  readonly node: string;
  readonly area: string | null;
  readonly online: boolean;
  readonly sinceWords: string;
  readonly hmiHref: string | null;
  /** The cell's history over the page's range (the shift): its first robot's recorded frames
   * in its panel, the plots opened at that range (`HMI/?robot=NAME&from=&to=`). */
  readonly historyHref: string | null;
  /** The plant process that follows the cell: null the page's own, else a peer's URL. */
  readonly peer: string | null;
  /** Its peer does not answer: the cell as last answered. */
  readonly peerDown: boolean;
  readonly figures: CellFigures | undefined;
  readonly figuresWords: string;
  readonly robots: readonly RobotRow[];
}

/** The HMI URL a node names, if it is an http(s) URL (never a script: it becomes a link). */
export function safeHmiUrl(url: string | null | undefined): string | null {
  if (url === null || url === undefined) return null;
  try {
    const parsed = new URL(url);
    return parsed.protocol === "http:" || parsed.protocol === "https:" ? parsed.href.replace(/\/$/, "") : null;
  } catch {
    return null;
  }
}

/** A robot's panel in its cell: the cell's HMI with `?robot=NAME` (lib/common/route.ts). */
export function robotPanelHref(hmi: string | null, device: string): string | null {
  return hmi === null ? null : `${hmi}/?${new URLSearchParams({ robot: device }).toString()}`;
}

/**
 * A robot's history in its cell over `[since_s, until_s]`: the cell's panel for the robot with
 * its plots opened at that range (`?robot=NAME&from=S&to=S`, epoch seconds: what the panel reads,
 * lib/common/route.ts `rangeFromSearch`), where its raw frames are. Null without an HMI address.
 */
export function cellHistoryHref(hmi: string | null, robot: string, since_s: number, until_s: number): string | null {
  return hmi === null ? null : `${hmi}${historyHref(robot, Math.floor(since_s), Math.ceil(until_s))}`;
}

/**
 * A robot's health in words: its verdict (its worst joint's: ok, watch, act) and each joint that
 * is not ok with its reason ("health watch · J3 watch: friction up 22 %"); a cell that publishes
 * other `Health/` metrics has them named. Null: the cell publishes no health.
 */
export function healthWords(health: Readonly<Record<string, string>>): string | null {
  const entries = Object.entries(health);
  if (entries.length === 0) return null;
  const verdict = health.Verdict;
  if (verdict === undefined) {
    return entries
      .sort(([a], [b]) => a.localeCompare(b))
      .map(([name, value]) => `${name} ${value}`)
      .join(" · ");
  }
  const joints = entries
    .map(([name, value]) => [/^(J\d+)\/Verdict$/.exec(name)?.[1], value] as const)
    .filter((pair): pair is readonly [string, string] => pair[0] !== undefined && pair[1] !== "ok")
    .sort(([a], [b]) => Number(a.slice(1)) - Number(b.slice(1)))
    .map(([joint, value]) => {
      const reason = health[`${joint}/Reason`];
      return reason !== undefined && reason !== "" ? `${joint} ${value}: ${reason}` : `${joint} ${value}`;
    });
  return [`health ${verdict}`, ...joints].join(" · ");
}

export interface PageRange {
  readonly since_s: number;
  readonly until_s: number;
}

export function robotRow(node: PlantNode, device: PlantDevice, shifts: ReadonlyMap<string, RobotShift>, now_ms: number, zone?: string, range?: PageRange): RobotRow {
  const online = node.online && device.online;
  const top = device.alarms_active[0];
  const hmi = safeHmiUrl(node.hmi_url);
  const key = `${cellKey(node.group, node.node)}/${device.device}`;
  return {
    key,
    group: node.group,
    node: node.node,
    device: device.device,
    online,
    sinceWords: sinceWords(online, online ? device.since : Math.max(node.online ? 0 : node.since, device.online ? 0 : device.since), now_ms, zone),
    state: stateView(device.state),
    stateGroup: device.state_group ?? null,
    topAlarm: top === undefined ? null : { priority: top.priority, text: top.text, paint: priorityPaint(top.priority) },
    alarmCount: device.alarms_active.length,
    cycleLastWords: secondsWords(device.cycle_last_s),
    cycleAverageWords: secondsWords(device.cycle_average_s),
    healthWords: healthWords(device.health),
    shift: shiftView(shifts.get(key)),
    panelHref: robotPanelHref(hmi, device.device),
    historyHref: range === undefined ? null : cellHistoryHref(hmi, device.device, range.since_s, range.until_s),
  };
}

/** Whether a robot passes the state filter. */
export function matchesState(row: RobotRow, state: StateFilter | null): boolean {
  if (state === null) return true;
  if (state === "offline") return !row.online;
  if (state === "alarm") return row.alarmCount > 0;
  return row.online && row.stateGroup === state;
}

/** The cards the page shows: cells of the chosen area, each with its robots that pass the
 * state filter (a cell left without any is not shown), in the API's order (group, node). */
export function cellCards(
  nodes: readonly PlantNode[],
  figures: readonly CellFigures[],
  shifts: readonly RobotShift[],
  filter: PlantFilter,
  range: PageRange,
  now_ms: number,
  zone?: string,
  downPeers: ReadonlySet<string> = new Set(),
): CellCard[] {
  const figuresOf = new Map(figures.map((f) => [cellKey(f.group, f.node), f]));
  const shiftOf = new Map(shifts.map((s) => [`${cellKey(s.group, s.node)}/${s.device}`, s]));
  const cards: CellCard[] = [];
  for (const node of nodes) {
    if (filter.area !== null && node.group !== filter.area) continue;
    const robots = node.devices.map((d) => robotRow(node, d, shiftOf, now_ms, zone, range)).filter((r) => matchesState(r, filter.state));
    if (filter.state !== null && robots.length === 0) continue;
    const key = cellKey(node.group, node.node);
    const hmi = safeHmiUrl(node.hmi_url);
    cards.push({
      key,
      group: node.group,
      node: node.node,
      area: node.area ?? null,
      online: node.online,
      sinceWords: sinceWords(node.online, node.since, now_ms, zone),
      hmiHref: hmi,
      historyHref: node.devices[0] === undefined ? null : cellHistoryHref(hmi, node.devices[0].device, range.since_s, range.until_s),
      peer: node.peer ?? null,
      peerDown: node.peer !== null && node.peer !== undefined && downPeers.has(node.peer),
      figures: figuresOf.get(key),
      figuresWords: figuresWords(figuresOf.get(key)),
      robots,
    });
  }
  return cards;
}

/** The peers (other plant processes, `--peer`) that do not answer, in words for the page's
 * banner: "plant process http://h:8101 does not answer since 07:21:04 (timed out): its cells
 * as last seen". */
export function downPeerWords(peers: readonly PlantPeer[], now_ms: number, zone?: string): readonly string[] {
  return peers
    .filter((p) => !p.answering)
    .map((p) => `plant process ${p.url} does not answer since ${formatMoment(p.since * 1000, now_ms, zone)}${p.error ? ` (${p.error})` : ""}: its cells as last seen`);
}

/** The peers that do not answer, by URL (`cellCards`' `downPeers`). */
export function downPeers(peers: readonly PlantPeer[]): ReadonlySet<string> {
  return new Set(peers.filter((p) => !p.answering).map((p) => p.url));
}

/** The areas to choose from: every Sparkplug group heard, sorted. */
export function areasOf(nodes: readonly PlantNode[]): readonly string[] {
  return [...new Set(nodes.map((n) => n.group))].sort();
}

/** How many robots are in each state filter (the filter buttons say so). */
export function stateCounts(nodes: readonly PlantNode[], area: string | null): Readonly<Record<StateFilter, number>> {
  const counts = Object.fromEntries(STATE_FILTERS.map((s) => [s, 0])) as Record<StateFilter, number>;
  const none = new Map<string, RobotShift>();
  for (const node of nodes) {
    if (area !== null && node.group !== area) continue;
    for (const device of node.devices) {
      const row = robotRow(node, device, none, 0);
      for (const state of STATE_FILTERS) if (matchesState(row, state)) counts[state]++;
    }
  }
  return counts;
}

// ---------------------------------------------------------------- the alarm list

export interface AlarmLine {
  readonly key: string;
  readonly priority: string;
  readonly paint: Paint;
  readonly timeWords: string;
  readonly cell: string;
  readonly robot: string;
  readonly text: string;
  /** "active", "cleared"; a replayed one (store and forward) says "(replayed)". */
  readonly transitionWords: string;
  readonly active: boolean;
}

/** The plant's alarm list, newest first as the API gives it, within the area filter. */
export function alarmLines(transitions: readonly PlantTransition[], area: string | null, now_ms: number, zone?: string, limit = 200): AlarmLine[] {
  const lines: AlarmLine[] = [];
  for (const [i, t] of transitions.entries()) {
    if (area !== null && t.group !== area) continue;
    lines.push({
      key: `${t.time}-${t.group}-${t.node}-${t.device}-${t.alarm}-${t.active ? 1 : 0}-${i}`,
      priority: t.priority,
      paint: priorityPaint(t.priority),
      timeWords: formatMoment(t.time * 1000, now_ms, zone),
      cell: t.node,
      robot: t.device,
      text: t.text,
      transitionWords: `${t.active ? "active" : "cleared"}${t.historical ? " (replayed)" : ""}`,
      active: t.active,
    });
    if (lines.length >= limit) break;
  }
  return lines;
}

// ---------------------------------------------------------------- the wall display's density

/** Row heights of the densities, in px at 1920 × 1080 (styles/plant.css keeps them). */
export const DENSITIES = { roomy: 56, compact: 40, dense: 30 } as const;
export type Density = keyof typeof DENSITIES;

/**
 * The roomiest density at which `robots` rows and `cells` card headers fit `columns` columns of
 * `height_px`: the wall display shows everything without scrolling, as large as it can. A fifth
 * of the height is kept for what columns waste (a cell's card is never split between two).
 */
export function densityFor(robots: number, cells: number, columns: number, height_px: number): Density {
  const header_px = 34;
  for (const density of ["roomy", "compact", "dense"] as const) {
    const needed = (robots * DENSITIES[density] + cells * header_px) / Math.max(columns, 1);
    if (needed <= height_px * 0.8) return density;
  }
  return "dense";
}
