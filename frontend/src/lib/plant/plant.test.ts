import { describe, expect, it } from "vitest";
import { LAYOUT } from "../../generated/layout";
import { stateBadge } from "../layout/stateBadge";
import { rangeFromSearch, robotFromSearch } from "../common/route";
import {
  NO_FILTER,
  alarmLines,
  areasOf,
  badActorWords,
  cellCards,
  cellHistoryHref,
  densityFor,
  downPeerWords,
  downPeers,
  figuresWords,
  healthWords,
  safeHmiUrl,
  secondsWords,
  shiftView,
  spanWords,
  stateCounts,
  stateView,
  wordsOfName,
  type CellFigures,
  type PlantDevice,
  type PlantNode,
  type PlantTransition,
} from "./plant";

const NOW_MS = Date.UTC(2026, 11, 7, 12, 0, 0);
const RANGE = { since_s: NOW_MS / 1000 - 3600, until_s: NOW_MS / 1000 };

function device(name: string, over: Partial<PlantDevice> = {}): PlantDevice {
  return {
    device: name,
    online: true,
    since: NOW_MS / 1000 - 600,
    state: "STANDALONE_RUNNING",
    state_group: "running",
    alarms_active: [],
    cycle_last_s: 12.34,
    cycle_average_s: 12.1,
    health: {},
    ...over,
  };
}

function node(group: string, name: string, devices: PlantDevice[], over: Partial<PlantNode> = {}): PlantNode {
  return { group, node: name, online: true, since: NOW_MS / 1000 - 3600, bd_seq: 0, hmi_url: `http://127.0.0.1:8000/`, area: null, devices, ...over };
}

const estop = { alarm: "estop", priority: "critical", text: "Emergency stop", since: NOW_MS / 1000 - 5 };

const PLANT: PlantNode[] = [
  node("body", "cell-1", [device("m1013"), device("m0609", { state: "STANDALONE_STANDBY", state_group: "standby" })]),
  node("paint", "cell-2", [device("m1013", { state: "EMERGENCY_STOP", state_group: "error", alarms_active: [estop] })]),
  node("paint", "cell-3", [device("r1")], { online: false, since: NOW_MS / 1000 - 60, hmi_url: null }),
];

describe("a robot's state", () => {
  it("is the layout's words and pendant colours for our cells", () => {
    const view = stateView("STANDALONE_RUNNING");
    expect(view.words).toBe("Standalone running");
    const badge = stateBadge(LAYOUT.robot_states.find((s) => s.name === "STANDALONE_RUNNING")!.value);
    expect(view.paints).toEqual(badge.paints);
    expect(view.alternating).toBe(badge.alternating);
  });

  it("is another edge node's own name in words, never a guess of colour", () => {
    expect(stateView("PAINTING_SLOWLY").words).toBe("Painting slowly");
    expect(stateView("PAINTING_SLOWLY").paints[0]?.background).toBe("#6b6b6b");
    expect(stateView(null).words).toBe("No state yet");
    expect(wordsOfName("__")).toBe("Unknown state");
  });
});

describe("the cells", () => {
  it("show every robot with its most urgent alarm, cycle times and links", () => {
    const cards = cellCards(PLANT, [], [], NO_FILTER, RANGE, NOW_MS, "UTC");
    expect(cards.map((c) => c.node)).toEqual(["cell-1", "cell-2", "cell-3"]);
    const robot = cards[1]!.robots[0]!;
    expect(robot.state.words).toBe("Emergency stop");
    expect(robot.topAlarm).toMatchObject({ priority: "critical", text: "Emergency stop" });
    expect(robot.topAlarm?.paint.background).toBe("#d32020");
    expect(robot.cycleLastWords).toBe("12.3 s");
    expect(robot.panelHref).toBe("http://127.0.0.1:8000/?robot=m1013");
    expect(cards[1]!.hmiHref).toBe("http://127.0.0.1:8000");
    // The History links open the robot's recorded frames in its cell's panel at the page's range.
    const range = `from=${Math.floor(RANGE.since_s)}&to=${Math.ceil(RANGE.until_s)}`;
    expect(robot.historyHref).toBe(`http://127.0.0.1:8000/?robot=m1013&${range}`);
    expect(cards[0]!.historyHref).toBe(`http://127.0.0.1:8000/?robot=m1013&${range}`);
    expect(cards[0]!.robots[1]!.historyHref).toBe(`http://127.0.0.1:8000/?robot=m0609&${range}`);
    expect(cards[2]!.historyHref).toBeNull(); // the cell names no HMI
    expect(cards.every((c) => c.peer === null && !c.peerDown)).toBe(true);
  });

  it("link a robot's history the way the cell's panel reads it (its robot and range)", () => {
    const href = cellHistoryHref("https://cell-2.plant.example:8443", "m1013", 1764547200.7, 1764576000.2);
    expect(href).toBe("https://cell-2.plant.example:8443/?robot=m1013&from=1764547200&to=1764576001");
    const search = new URL(href!).search;
    expect(robotFromSearch(search)).toBe("m1013");
    expect(rangeFromSearch(search)).toEqual({ from_s: 1764547200, to_s: 1764576001 });
  });

  it("say which peer follows a cell, and grey a cell whose peer does not answer", () => {
    const peer = "http://127.5.0.2:8152";
    const nodes = [...PLANT, node("east", "cell-e", [device("r1")], { peer })];
    const peers = [{ url: peer, answering: false, since: NOW_MS / 1000 - 30, error: "timed out", nodes: 1 }];
    const cards = cellCards(nodes, [], [], NO_FILTER, RANGE, NOW_MS, "UTC", downPeers(peers));
    expect(cards.map((c) => [c.node, c.peer, c.peerDown])).toEqual([
      ["cell-1", null, false],
      ["cell-2", null, false],
      ["cell-3", null, false],
      ["cell-e", peer, true],
    ]);
    expect(downPeerWords(peers, NOW_MS, "UTC")).toEqual([`plant process ${peer} does not answer since 11:59:30 (timed out): its cells as last seen`]);
    expect(downPeerWords([{ ...peers[0]!, answering: true }], NOW_MS, "UTC")).toEqual([]);
  });

  it("mark an offline cell's robots offline since the cell's death, their last state kept", () => {
    const [offline] = cellCards(PLANT, [], [], { area: null, state: "offline" }, RANGE, NOW_MS, "UTC");
    expect(offline?.node).toBe("cell-3");
    expect(offline?.sinceWords).toBe("offline since 11:59:00");
    expect(offline?.robots[0]?.online).toBe(false);
    expect(offline?.robots[0]?.sinceWords).toBe("offline since 11:59:00");
    expect(offline?.robots[0]?.state.words).toBe("Standalone running");
    expect(offline?.hmiHref).toBeNull();
  });

  it("filter by area and by state group, leaving out cells with no robot left", () => {
    const paint = cellCards(PLANT, [], [], { area: "paint", state: null }, RANGE, NOW_MS);
    expect(paint.map((c) => c.node)).toEqual(["cell-2", "cell-3"]);
    const standby = cellCards(PLANT, [], [], { area: null, state: "standby" }, RANGE, NOW_MS);
    expect(standby.map((c) => [c.node, c.robots.map((r) => r.device)])).toEqual([["cell-1", ["m0609"]]]);
    // An offline robot is not "running", whatever it last said.
    const running = cellCards(PLANT, [], [], { area: "paint", state: "running" }, RANGE, NOW_MS);
    expect(running).toEqual([]);
    expect(cellCards(PLANT, [], [], { area: null, state: "alarm" }, RANGE, NOW_MS).map((c) => c.node)).toEqual(["cell-2"]);
  });

  it("count each state for the filter's buttons, within the area", () => {
    expect(stateCounts(PLANT, null)).toEqual({ running: 1, standby: 1, stopped: 0, error: 1, offline: 1, alarm: 1 });
    expect(stateCounts(PLANT, "body")).toMatchObject({ running: 1, standby: 1, error: 0 });
    expect(areasOf(PLANT)).toEqual(["body", "paint"]);
  });

  it("never link a node's HMI URL that is not http(s)", () => {
    expect(safeHmiUrl("javascript:alert(1)")).toBeNull();
    expect(safeHmiUrl("not a url")).toBeNull();
    expect(safeHmiUrl("https://cell-2.plant.example:8443/")).toBe("https://cell-2.plant.example:8443");
    expect(cellHistoryHref(null, "m1013", 0, 1)).toBeNull();
  });
});

describe("a robot's health", () => {
  it("is its verdict and each joint not ok with its reason, never every life-used figure", () => {
    const health = { Verdict: "watch", "J1/Verdict": "ok", "J1/Life Used": "3.2", "J3/Verdict": "watch", "J3/Reason": "friction up 22 %", "J12/Verdict": "act" };
    expect(healthWords(health)).toBe("health watch · J3 watch: friction up 22 % · J12 act");
    expect(healthWords({ Verdict: "ok", "J1/Verdict": "ok" })).toBe("health ok");
    expect(healthWords({ friction: "watch", reducer: "ok" })).toBe("friction watch · reducer ok");
    expect(healthWords({})).toBeNull();
  });
});

describe("the figures in words", () => {
  const figures = (over: Partial<CellFigures>): CellFigures => ({
    group: "paint",
    node: "cell-2",
    alarms_per_10_min: 2.345,
    flood: false,
    peak_per_10_min: 4,
    bad_actors: [["m1013", "estop", 12]],
    ...over,
  });

  it("say the rate per 10 minutes, and a flood as such", () => {
    expect(figuresWords(undefined)).toBe("no alarms");
    expect(figuresWords(figures({}))).toBe("2.3 per 10 min");
    expect(figuresWords(figures({ flood: true, peak_per_10_min: 14, alarms_per_10_min: 12.6 }))).toBe("FLOOD (14 in 10 min) · 13 per 10 min");
    expect(badActorWords(figures({}))).toEqual(["m1013 estop ×12"]);
  });

  it("are each cell's on its card", () => {
    const [card] = cellCards(PLANT, [figures({ flood: true, peak_per_10_min: 11 })], [], { area: "paint", state: null }, RANGE, NOW_MS);
    expect(card?.figuresWords).toMatch(/^FLOOD/);
  });

  it("say times and spans briefly", () => {
    expect(secondsWords(null)).toBe("—");
    expect(secondsWords(123.4)).toBe("123 s");
    expect(spanWords(42)).toBe("42 s");
    expect(spanWords(12 * 60 + 5)).toBe("12 min");
    expect(spanWords(3 * 3600 + 5 * 60)).toBe("3 h 05 min");
  });
});

describe("a robot's shift", () => {
  it("has each state group's share of the known time, the cycles and their mean", () => {
    const view = shiftView({ group: "g", node: "n", device: "d", seconds: { running: 3000, standby: 600, stopped: 0, error: 0, unknown: 400 }, cycles: 250, mean_cycle_s: 12.04 });
    expect(view?.fractions).toEqual([3000 / 3600, 600 / 3600, 0, 0]);
    expect(view?.words).toBe("running 50 min, standby 10 min, stopped 0 s, error 0 s; 250 cycles, mean 12.0 s");
    expect(shiftView(undefined)).toBeNull();
  });

  it("is found by group, node and device", () => {
    const shift = { group: "body", node: "cell-1", device: "m0609", seconds: { running: 60 }, cycles: 1, mean_cycle_s: 9 };
    const [card] = cellCards(PLANT, [], [shift], NO_FILTER, RANGE, NOW_MS);
    expect(card?.robots.map((r) => r.shift?.cycles ?? null)).toEqual([null, 1]);
  });
});

describe("the alarm list", () => {
  const t = (over: Partial<PlantTransition>): PlantTransition => ({
    time: NOW_MS / 1000 - 30,
    group: "paint",
    node: "cell-2",
    device: "m1013",
    alarm: "estop",
    active: true,
    priority: "critical",
    text: "Emergency stop",
    historical: false,
    ...over,
  });

  it("says priority, time, cell, robot and text, a replayed one as such, within the area", () => {
    const lines = alarmLines([t({}), t({ group: "body", node: "cell-1", active: false, historical: true, priority: "low" })], null, NOW_MS, "UTC");
    expect(lines.map((l) => [l.priority, l.timeWords, l.cell, l.robot, l.text, l.transitionWords])).toEqual([
      ["critical", "11:59:30", "cell-2", "m1013", "Emergency stop", "active"],
      ["low", "11:59:30", "cell-1", "m1013", "Emergency stop", "cleared (replayed)"],
    ]);
    expect(alarmLines([t({}), t({ group: "body" })], "body", NOW_MS).length).toBe(1);
    expect(alarmLines([t({}), t({}), t({})], null, NOW_MS, "UTC", 2).length).toBe(2);
  });
});

describe("the wall display's density", () => {
  it("is as roomy as fits: 50 robots of 10 cells in four columns of 1080 px fit compact", () => {
    expect(densityFor(8, 2, 4, 970)).toBe("roomy");
    expect(densityFor(50, 10, 4, 970)).toBe("compact");
    expect(densityFor(50, 50, 4, 970)).toBe("dense");
    expect(densityFor(500, 50, 4, 970)).toBe("dense");
  });
});
