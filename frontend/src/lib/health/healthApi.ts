/**
 * Layer: the health page's and the fleet's REST calls (docs/api.md "Health"; no React, no DOM):
 * a robot's report, its trend over a range, its baselines and a re-baselining, through the
 * generated client (lib/api/api.ts), so a path or a body the service does not have fails to
 * compile. The kiosk never imports this module (it reads its mark with a plain GET:
 * lib/health/maintenanceMark.ts).
 */
import { api, errorReason, type JsonClient } from "../api/api";
import type { HttpAnswer } from "../writes/writes";
import type { Fetched } from "../common/poller";
import type { BaselineList, BaselineRequest, HealthAnswer, TrendAnswer } from "./healthTypes";

/**
 * How often the health page asks for its report: the service judges the verdicts again every few
 * seconds (`health_report_s`), so a poll every few seconds shows every change.
 */
export const HEALTH_POLL_MS = 3000;

/** What openapi-fetch gives back. */
interface Result<T> {
  readonly data?: T;
  readonly error?: unknown;
  readonly response: Response;
}

function fetched<T>(result: Result<T>): Fetched<T> {
  const status = result.response.status;
  if (status === 200 && result.data !== undefined) return { ok: true, value: result.data };
  return { ok: false, status, reason: errorReason({ status, body: result.error ?? null }) };
}

export class HealthApi {
  constructor(private readonly client: JsonClient) {}

  async report(robot: string): Promise<Fetched<HealthAnswer>> {
    return fetched(await this.client.GET("/api/v1/robots/{name}/health", { params: { path: { name: robot } } }));
  }

  async trend(robot: string, from_s: number, to_s: number): Promise<Fetched<TrendAnswer>> {
    const query = { from: String(from_s), to: String(to_s) };
    return fetched(await this.client.GET("/api/v1/robots/{name}/health/trend", { params: { path: { name: robot }, query } }));
  }

  async baselines(robot: string): Promise<Fetched<BaselineList>> {
    return fetched(await this.client.GET("/api/v1/robots/{name}/health/baselines", { params: { path: { name: robot } } }));
  }

  /** Learn a new baseline (operator; audited): 201 with its record, or the refusal. */
  async setBaseline(robot: string, body: BaselineRequest): Promise<HttpAnswer> {
    const result = await this.client.POST("/api/v1/robots/{name}/health/baselines", { params: { path: { name: robot } }, body });
    return { status: result.response.status, body: result.data ?? result.error ?? null };
  }
}

export const healthApi = new HealthApi(api.client);
