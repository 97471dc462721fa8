/**
 * Layer: the fleet overview's health column (no React, no DOM): each robot's worst verdict and
 * whether maintenance is due, asked of `GET …/health` robot by robot, one after the other, every
 * `FLEET_HEALTH_POLL_MS` (the verdicts change in minutes, not in seconds). A robot whose health
 * could not be read says why, never "ok".
 */
import { healthHref } from "../common/route";
import type { Fetched } from "../common/poller";
import type { HealthAnswer, Verdict } from "./healthTypes";
import { maintenanceMark } from "./maintenanceMark";
import { isVerdict, robotVerdictWords, worstVerdict } from "./verdicts";

export const FLEET_HEALTH_POLL_MS = 10_000;

export interface RobotHealthCell {
  /** The worst verdict of its joints (null: not known). */
  readonly verdict: Verdict | null;
  /** "act: J3", "ok", or why it is not known. */
  readonly words: string;
  readonly maintenanceDue: boolean;
  readonly href: string;
}

/** A robot's cell of the column from its health answer (or why there is none). */
export function healthCell(robot: string, answer: Fetched<HealthAnswer> | null): RobotHealthCell {
  const href = healthHref(robot);
  if (answer === null) return { verdict: null, words: "asking…", maintenanceDue: false, href };
  if (!answer.ok) return { verdict: null, words: `not known: ${answer.reason}`, maintenanceDue: false, href };
  const report = answer.value;
  const verdict = isVerdict(report.verdict) ? report.verdict : worstVerdict(report.joints);
  const learning = report.baseline == null;
  const words = learning && verdict === "ok" ? "no baseline yet" : robotVerdictWords(report.joints);
  return { verdict, words, maintenanceDue: maintenanceMark(report).due, href };
}

type Listener = () => void;

/** Polls the health of the robots it is given; `cells` maps a robot's name to its cell. */
export class FleetHealthPoller {
  private readonly listeners = new Set<Listener>();
  private robots: readonly string[] = [];
  private answers = new Map<string, Fetched<HealthAnswer>>();
  private current: ReadonlyMap<string, RobotHealthCell> = new Map();
  private timer: ReturnType<typeof setTimeout> | null = null;
  private running = false;
  private generation = 0;

  constructor(
    private readonly fetchHealth: (robot: string) => Promise<Fetched<HealthAnswer>>,
    private readonly interval_ms = FLEET_HEALTH_POLL_MS,
  ) {}

  subscribe = (listener: Listener): (() => void) => {
    this.listeners.add(listener);
    return () => {
      this.listeners.delete(listener);
    };
  };

  getSnapshot = (): ReadonlyMap<string, RobotHealthCell> => this.current;

  /** The robots to ask about (the fleet's list, as it changes); a new robot is asked at once. */
  setRobots(robots: readonly string[]): void {
    const added = robots.some((r) => !this.robots.includes(r));
    this.robots = [...robots];
    this.publish();
    if (added && this.running) this.restart();
  }

  start(): void {
    if (this.running) return;
    this.running = true;
    this.restart();
  }

  stop(): void {
    this.running = false;
    this.generation++;
    if (this.timer !== null) clearTimeout(this.timer);
    this.timer = null;
  }

  private restart(): void {
    if (this.timer !== null) clearTimeout(this.timer);
    this.timer = null;
    void this.poll(++this.generation);
  }

  private publish(): void {
    this.current = new Map(this.robots.map((r) => [r, healthCell(r, this.answers.get(r) ?? null)]));
    for (const listener of this.listeners) listener();
  }

  private async poll(generation: number): Promise<void> {
    for (const robot of this.robots) {
      let answer: Fetched<HealthAnswer>;
      try {
        answer = await this.fetchHealth(robot);
      } catch (error) {
        answer = { ok: false, status: 0, reason: error instanceof Error ? error.message : String(error) };
      }
      if (!this.running || generation !== this.generation) return;
      this.answers.set(robot, answer);
      this.publish();
    }
    this.timer = setTimeout(() => {
      this.timer = null;
      void this.poll(generation);
    }, this.interval_ms);
  }
}
