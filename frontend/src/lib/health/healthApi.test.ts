// The health calls over the generated client: which request each sends (method, path, query,
// content type, body) and how it reads the answers. The service is stood in for by a fetch that
// records the request and answers as the service does (docs/api.md "Health"); the real service
// is exercised end to end in e2e/tests/44-health.spec.ts.
import createClient from "openapi-fetch";
import { describe, expect, it } from "vitest";
import type { paths } from "../../generated/api";
import { HealthApi } from "./healthApi";
import { report, SIX_OK } from "./healthTestSupport";

function service(status: number, answer: unknown) {
  const seen: { method: string; path: string; query: Record<string, string>; contentType: string | null; body: unknown }[] = [];
  const fetch = async (request: Request): Promise<Response> => {
    const url = new URL(request.url);
    const text = await request.text();
    seen.push({
      method: request.method,
      path: url.pathname,
      query: Object.fromEntries(url.searchParams),
      contentType: request.headers.get("content-type"),
      body: text === "" ? undefined : JSON.parse(text),
    });
    return new Response(JSON.stringify(answer), { status, headers: { "Content-Type": "application/json" } });
  };
  return { api: new HealthApi(createClient<paths, "application/json">({ baseUrl: "http://hmi.test", fetch })), seen };
}

describe("HealthApi", () => {
  it("reads a robot's report", async () => {
    const answer = report(SIX_OK);
    const { api, seen } = service(200, answer);
    expect(await api.report("m1013")).toEqual({ ok: true, value: answer });
    expect(seen).toMatchObject([{ method: "GET", path: "/api/v1/robots/m1013/health" }]);
  });

  it("reads the trend over a range, from and to in seconds", async () => {
    const { api, seen } = service(200, { robot: "m1013", points: [] });
    expect(await api.trend("m1013", 100, 200)).toEqual({ ok: true, value: { robot: "m1013", points: [] } });
    expect(seen).toMatchObject([{ method: "GET", path: "/api/v1/robots/m1013/health/trend", query: { from: "100", to: "200" } }]);
  });

  it("says why there is no answer, with its status", async () => {
    const { api } = service(404, { detail: { reason: "no robot x (known: m1013)", field: null } });
    expect(await api.report("x")).toEqual({ ok: false, status: 404, reason: "no robot x (known: m1013)" });
  });

  it("asks for a new baseline as JSON, and hands back the refusal", async () => {
    const { api, seen } = service(403, { detail: { reason: "operator role required", field: null } });
    const answer = await api.setBaseline("m1013", { reason: "J3 reducer replaced", cycles: 20 });
    expect(answer.status).toBe(403);
    expect(seen).toMatchObject([
      { method: "POST", path: "/api/v1/robots/m1013/health/baselines", contentType: "application/json", body: { reason: "J3 reducer replaced", cycles: 20 } },
    ]);
    const { api: lists, seen: listed } = service(200, { items: [] });
    expect(await lists.baselines("m1013")).toEqual({ ok: true, value: { items: [] } });
    expect(listed).toMatchObject([{ method: "GET", path: "/api/v1/robots/m1013/health/baselines" }]);
  });
});
