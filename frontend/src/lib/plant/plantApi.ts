/**
 * Layer: the plant page's REST client and its poller (no React, no DOM): openapi-fetch over the
 * types generated from the plant's OpenAPI document (`src/generated/plantApi.ts`, from
 * docs/plant-openapi.json), same-origin with the session cookie, as the panel's client is.
 *
 * The page is live by polling: the edge nodes every `NODES_POLL_MS` (a change is on the page
 * within that plus one answer: well under a second), the alarm list and figures every
 * `ALARMS_POLL_MS`, the shift's figures (read from the plant's history) every `SHIFTS_POLL_MS`.
 * One request of each kind at a time: a slow answer delays the next rather than piling up.
 */
import createClient, { type Client } from "openapi-fetch";
import type { paths } from "../../generated/plantApi";
import type { PlantAlarms, PlantNode, PlantPeer, PlantShifts } from "./plant";

export const NODES_POLL_MS = 250;
export const ALARMS_POLL_MS = 1000;
export const SHIFTS_POLL_MS = 30_000;
/** The alarm list's length (the figures count every transition of the range). */
export const ALARM_LIST_LIMIT = 200;

type PlantClient = Client<paths, "application/json">;

/** An answer, or why there is none (`status` 401: a login is needed). */
export type Answer<T> = { readonly ok: true; readonly data: T } | { readonly ok: false; readonly status: number; readonly reason: string };

interface Fetched<T> {
  readonly data?: T;
  readonly error?: unknown;
  readonly response: Response;
}

/** `T`: the generated type of the answer (openapi-fetch widens a tuple such as `bad_actors`'
 * `[device, alarm, count]` into an array of its members' union; the document says the tuple). */
function answerOf<T>(result: Fetched<unknown>): Answer<T> {
  if (result.data !== undefined && result.response.ok) return { ok: true, data: result.data as T };
  const detail = (result.error as { detail?: unknown } | undefined)?.detail;
  const reason =
    typeof detail === "string"
      ? detail
      : typeof (detail as { reason?: unknown } | undefined)?.reason === "string"
        ? (detail as { reason: string }).reason
        : `HTTP ${result.response.status}`;
  return { ok: false, status: result.response.status, reason };
}

export class PlantApi {
  constructor(readonly client: PlantClient) {}

  async nodes(): Promise<Answer<PlantNode[]>> {
    return answerOf<PlantNode[]>(await this.client.GET("/api/v1/plant/nodes"));
  }

  async alarms(since_s: number): Promise<Answer<PlantAlarms>> {
    return answerOf<PlantAlarms>(await this.client.GET("/api/v1/plant/alarms", { params: { query: { since: since_s, limit: ALARM_LIST_LIMIT } } }));
  }

  async shifts(): Promise<Answer<PlantShifts>> {
    return answerOf<PlantShifts>(await this.client.GET("/api/v1/plant/shifts"));
  }

  /** The other plant processes whose cells the page shows (`--peer`), answering or not. */
  async peers(): Promise<Answer<PlantPeer[]>> {
    return answerOf<PlantPeer[]>(await this.client.GET("/api/v1/plant/peers"));
  }

  async me(): Promise<string | null> {
    const result = await this.client.GET("/api/v1/auth/me");
    return result.data?.user?.name ?? null;
  }

  async login(username: string, password: string): Promise<Answer<unknown>> {
    return answerOf<unknown>(await this.client.POST("/api/v1/auth/login", { body: { username, password } }));
  }

  async logout(): Promise<void> {
    await this.client.POST("/api/v1/auth/logout", { headers: { "Content-Type": "application/json" } });
  }
}

export const plantApi = new PlantApi(createClient<paths, "application/json">({ credentials: "same-origin" }));

/** What the page shows: the last good answer of each kind, and whether they are current. */
export interface PlantSnapshot {
  readonly nodes: readonly PlantNode[];
  readonly alarms: PlantAlarms | null;
  readonly shifts: PlantShifts | null;
  /** The plant's other processes (`--peer`), polled with the alarms. */
  readonly peers: readonly PlantPeer[];
  /** Why the last poll of the nodes failed, null when it succeeded. */
  readonly error: string | null;
  /** The plant asks for a login (401). */
  readonly loginNeeded: boolean;
  /** A first answer of the nodes (good or bad) has come. */
  readonly loaded: boolean;
  /** The nodes shown are older than the newest poll. */
  readonly stale: boolean;
  /** When the nodes shown were answered (epoch ms). */
  readonly answered_ms: number;
}

export const EMPTY_SNAPSHOT: PlantSnapshot = {
  nodes: [],
  alarms: null,
  shifts: null,
  peers: [],
  error: null,
  loginNeeded: false,
  loaded: false,
  stale: false,
  answered_ms: 0,
};

/** The range the alarm list covers before the shift's start is known: the last 8 hours. */
const DEFAULT_RANGE_S = 8 * 3600;

type Listener = () => void;

/** Polls the three answers, each on its own clock, and publishes snapshots. */
export class PlantPoller {
  private readonly listeners = new Set<Listener>();
  private readonly timers = new Set<ReturnType<typeof setTimeout>>();
  private running = false;
  private generation = 0;
  private current: PlantSnapshot = EMPTY_SNAPSHOT;

  constructor(
    private readonly api: Pick<PlantApi, "nodes" | "alarms" | "shifts"> & Partial<Pick<PlantApi, "peers">>,
    private readonly now_ms: () => number = Date.now,
  ) {}

  subscribe = (listener: Listener): (() => void) => {
    this.listeners.add(listener);
    return () => {
      this.listeners.delete(listener);
    };
  };

  getSnapshot = (): PlantSnapshot => this.current;

  start(): void {
    if (this.running) return;
    this.running = true;
    const generation = ++this.generation;
    void this.loop(generation, NODES_POLL_MS, () => this.pollNodes());
    void this.loop(generation, ALARMS_POLL_MS, () => this.pollAlarms());
    void this.loop(generation, SHIFTS_POLL_MS, () => this.pollShifts());
    if (this.api.peers !== undefined) void this.loop(generation, ALARMS_POLL_MS, () => this.pollPeers());
  }

  stop(): void {
    this.running = false;
    this.generation++;
    for (const timer of this.timers) clearTimeout(timer);
    this.timers.clear();
  }

  /** Start again at once (after a login). */
  restart(): void {
    this.stop();
    this.start();
  }

  private publish(next: Partial<PlantSnapshot>): void {
    this.current = { ...this.current, ...next };
    for (const listener of this.listeners) listener();
  }

  private async loop(generation: number, interval_ms: number, poll: () => Promise<Partial<PlantSnapshot> | null>): Promise<void> {
    let next: Partial<PlantSnapshot> | null;
    try {
      next = await poll();
    } catch (error) {
      next = { error: error instanceof Error ? error.message : String(error), stale: this.current.loaded, loaded: true };
    }
    if (!this.running || generation !== this.generation) return;
    if (next !== null) this.publish(next);
    const timer = setTimeout(() => {
      this.timers.delete(timer);
      void this.loop(generation, interval_ms, poll);
    }, interval_ms);
    this.timers.add(timer);
  }

  private async pollNodes(): Promise<Partial<PlantSnapshot>> {
    const answer = await this.api.nodes();
    if (answer.ok) return { nodes: answer.data, error: null, loginNeeded: false, loaded: true, stale: false, answered_ms: this.now_ms() };
    return { error: answer.reason, loginNeeded: answer.status === 401, loaded: true, stale: this.current.answered_ms > 0 };
  }

  private async pollAlarms(): Promise<Partial<PlantSnapshot> | null> {
    const since_s = this.current.shifts?.since ?? this.now_ms() / 1000 - DEFAULT_RANGE_S;
    const answer = await this.api.alarms(since_s);
    return answer.ok ? { alarms: answer.data } : null;
  }

  private async pollPeers(): Promise<Partial<PlantSnapshot> | null> {
    const answer = await this.api.peers?.();
    return answer?.ok === true ? { peers: answer.data } : null;
  }

  private async pollShifts(): Promise<Partial<PlantSnapshot> | null> {
    const answer = await this.api.shifts();
    return answer.ok ? { shifts: answer.data } : null;
  }
}
