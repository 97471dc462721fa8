/**
 * Layer: the panel's REST calls for the I/O checkout (docs/api.md "I/O checkout") over the typed
 * client of `lib/api/api.ts`, and the pure helpers its view needs (filtering points, the counts in
 * words, a point's state in words). No React.
 */
import { API, api, errorReason, type JsonClient, type PageAnswer } from "../api/api";
import type { components } from "../../generated/api";
import { formatClock } from "../common/dates";
import type { HttpAnswer } from "../writes/writes";

type Schemas = components["schemas"];
export type Checkout = Schemas["Checkout"];
export type CheckoutPoint = Schemas["CheckoutPoint"];
export type CheckoutSummary = Schemas["CheckoutSummary"];
export type CheckoutResult = CheckoutPoint["result"];
export type CheckoutSwitch = Schemas["CheckoutSwitchRecord"];

const JSON_CONTENT = { "Content-Type": "application/json" } as const;

interface Fetched<T> {
  readonly data?: T;
  readonly error?: unknown;
  readonly response: Response;
}

/** What openapi-fetch gave back as a page answer: the data when the status is `ok`, else the reason (also the presets' calls). */
export function pageOf<T>(result: Fetched<T>, ok = 200): PageAnswer<T> {
  if (result.data !== undefined && result.response.status === ok) return { ok: true, page: result.data };
  const answer: HttpAnswer = { status: result.response.status, body: result.data ?? result.error ?? null };
  return { ok: false, status: answer.status, reason: errorReason(answer) };
}

export class CheckoutApi {
  constructor(readonly client: JsonClient) {}

  async list(robot: string): Promise<PageAnswer<Schemas["CheckoutList"]>> {
    return pageOf(await this.client.GET("/api/v1/robots/{name}/checkouts", { params: { path: { name: robot } } }));
  }

  async start(robot: string): Promise<PageAnswer<Checkout>> {
    const result = await this.client.POST("/api/v1/robots/{name}/checkouts", { params: { path: { name: robot } }, headers: JSON_CONTENT });
    return pageOf(result, 201);
  }

  async get(robot: string, id: number): Promise<PageAnswer<Checkout>> {
    return pageOf(
      await this.client.GET("/api/v1/robots/{name}/checkouts/{checkout_id}", { params: { path: { name: robot, checkout_id: id } } }),
    );
  }

  async record(robot: string, id: number, key: string, result: "pass" | "fail", comment: string): Promise<PageAnswer<CheckoutPoint>> {
    return pageOf(
      await this.client.POST("/api/v1/robots/{name}/checkouts/{checkout_id}/points/{key}/result", {
        params: { path: { name: robot, checkout_id: id, key } },
        body: { result, comment },
        headers: JSON_CONTENT,
      }),
    );
  }

  async switchOutput(robot: string, id: number, key: string, value: boolean | number): Promise<PageAnswer<CheckoutPoint>> {
    return pageOf(
      await this.client.POST("/api/v1/robots/{name}/checkouts/{checkout_id}/points/{key}/switch", {
        params: { path: { name: robot, checkout_id: id, key } },
        body: { value },
        headers: JSON_CONTENT,
      }),
    );
  }

  async capture(robot: string, id: number, key: string): Promise<PageAnswer<CheckoutPoint>> {
    return pageOf(
      await this.client.POST("/api/v1/robots/{name}/checkouts/{checkout_id}/points/{key}/capture", {
        params: { path: { name: robot, checkout_id: id, key } },
        headers: JSON_CONTENT,
      }),
    );
  }

  async close(robot: string, id: number): Promise<PageAnswer<Checkout>> {
    return pageOf(
      await this.client.POST("/api/v1/robots/{name}/checkouts/{checkout_id}/close", {
        params: { path: { name: robot, checkout_id: id } },
        headers: JSON_CONTENT,
      }),
    );
  }
}

export const checkoutApi = new CheckoutApi(api.client);

export function checkoutCsvUrl(robot: string, id: number): string {
  return `${API}/robots/${encodeURIComponent(robot)}/checkouts/${id}/report.csv`;
}

export type PointFilter = "all" | "inputs" | "outputs" | "open" | "done";

/** The points a filter and a search text keep (label, key or tag name; case ignored). */
export function filterPoints(points: readonly CheckoutPoint[], filter: PointFilter, text: string): CheckoutPoint[] {
  const q = text.trim().toLowerCase();
  return points.filter((p) => {
    if (filter === "inputs" && p.kind !== "input") return false;
    if (filter === "outputs" && p.kind !== "output") return false;
    if (filter === "open" && (p.result === "pass" || p.result === "fail")) return false;
    if (filter === "done" && p.result === "untested") return false;
    if (q === "") return true;
    return p.label.toLowerCase().includes(q) || p.key.includes(q) || (p.tag ?? "").toLowerCase().includes(q);
  });
}

/** "12 pass, 1 fail, 3 seen, 160 untested" */
export function countsWords(counts: CheckoutSummary["counts"]): string {
  return `${counts.pass} pass, ${counts.fail} fail, ${counts.seen} seen, ${counts.untested} untested`;
}

function valueWords(value: boolean | number | null | undefined): string {
  if (value === null || value === undefined) return "";
  if (typeof value === "boolean") return value ? "on" : "off";
  return String(value);
}

/** One switch of an output as the evidence lists it: "on confirmed 07:21:04". */
export function switchWords(s: CheckoutSwitch, clock: (epoch_ms: number) => string = formatClock): string {
  return `${valueWords(s.value)} confirmed ${clock(s.time * 1000)}`;
}

/**
 * What the frames or the robot showed of a point, in words: "off → on", "4, 20", and for an
 * output every switch the robot confirmed, in order ("on confirmed 07:21:04, off confirmed
 * 07:21:09"): a pass keeps what proved it after the output is switched off again.
 */
export function evidenceWords(p: CheckoutPoint, clock: (epoch_ms: number) => string = formatClock): string {
  if (p.kind === "input" && p.signal === "digital") {
    return p.seen_at === null ? "" : `${valueWords(p.seen_before)} → ${valueWords(p.seen_after)}`;
  }
  if (p.kind === "input") return p.samples.map((s) => s.value.toFixed(3)).join(", ");
  if (p.switches.length > 0) return p.switches.map((s) => switchWords(s, clock)).join(", ");
  return p.switched_at === null ? "" : `${valueWords(p.switched_value)} (confirmed)`;
}

/** Why the checker's verdict cannot be sent yet ("a fail needs a comment"), or null. */
export function verdictRefusal(result: "pass" | "fail", comment: string): string | null {
  return result === "fail" && comment.trim() === "" ? "A fail needs a comment saying what is wrong." : null;
}

/** The robot's open checkout (at most one): resumed rather than a second one started. */
export function openCheckout(list: readonly CheckoutSummary[]): CheckoutSummary | null {
  return list.find((c) => c.closed_at === null) ?? null;
}

/** When the point last changed: its verdict, else what the robot showed. */
export function pointTime_s(p: CheckoutPoint): number | null {
  return p.recorded_at ?? p.switched_at ?? p.seen_at ?? p.samples[p.samples.length - 1]?.time ?? null;
}

/** Who did it: the checker's name, else who switched or captured it. */
export function pointWho(p: CheckoutPoint): string {
  return p.recorded_by ?? p.switched_by ?? p.samples[p.samples.length - 1]?.by ?? "";
}
