// The REST client over openapi-fetch: which request each call sends (method, path, query,
// content type, body) and how it reads the answers. The service is stood in for by a fetch
// that records the request and answers as the service does (docs/api.md); the real service is
// exercised end to end in e2e/.
import createClient from "openapi-fetch";
import { describe, expect, it } from "vitest";
import type { paths } from "../../generated/api";
import { auditCsvUrl, controlOf, errorReason, eventsCsvUrl, HmiApi } from "./api";

interface Seen {
  readonly method: string;
  readonly path: string;
  readonly query: Record<string, string>;
  readonly contentType: string | null;
  readonly body: unknown;
}

function service(status: number, answer: unknown) {
  const seen: Seen[] = [];
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
  const api = new HmiApi(createClient<paths, "application/json">({ baseUrl: "http://hmi.test", fetch }));
  return { api, seen };
}

const REFUSED = { detail: { reason: "alice holds control", field: null } };

describe("HmiApi", () => {
  it("lists the robots", async () => {
    const robots = [{ name: "m1013" }, { name: "m0609" }];
    const { api, seen } = service(200, { robots });
    expect(await api.robots()).toEqual({ ok: true, robots });
    expect(seen).toMatchObject([{ method: "GET", path: "/api/v1/robots" }]);
  });

  it("says why there is no list", async () => {
    const { api } = service(401, { detail: { reason: "login required", field: null } });
    expect(await api.robots()).toEqual({ ok: false, reason: "login required" });
  });

  it("takes and releases control of the named robot, as JSON (never as a form post)", async () => {
    const { api, seen } = service(200, { holder: { user: "op", since: 5 } });
    const answer = await api.takeControl("m0609");
    expect(controlOf(answer)).toEqual({ holder: { user: "op", since: 5 } });
    await api.releaseControl("m0609");
    expect(seen.map((s) => [s.method, s.path, s.contentType])).toEqual([
      ["POST", "/api/v1/robots/m0609/control/take", "application/json"],
      ["POST", "/api/v1/robots/m0609/control/release", "application/json"],
    ]);
  });

  it("writes a patch to the named robot's command and hands back status and body", async () => {
    const { api, seen } = service(409, REFUSED);
    const answer = await api.patchCommand("m1013", { controlbox_do: { "2": true } });
    expect(answer).toEqual({ status: 409, body: REFUSED });
    expect(errorReason(answer)).toBe("alice holds control");
    expect(controlOf(answer)).toBeNull();
    expect(seen).toEqual([
      {
        method: "PATCH",
        path: "/api/v1/robots/m1013/command",
        query: {},
        contentType: "application/json",
        body: { controlbox_do: { "2": true } },
      },
    ]);
  });

  it("reads the command image being sent, null when refused", async () => {
    const image = { robot: "m1013", image: { controlbox_do: [] }, run: true };
    const ok = service(200, image);
    expect(await ok.api.command("m1013")).toEqual(image);
    expect(ok.seen[0]?.path).toBe("/api/v1/robots/m1013/command");
    expect(await service(404, { detail: { reason: "unknown robot", field: "name" } }).api.command("x")).toBeNull();
  });

  it("asks for one robot's events and audit", async () => {
    const page = { items: [], total: 0 };
    const { api, seen } = service(200, page);
    expect(await api.events("m0609", "write", 100, 0)).toEqual({ ok: true, page });
    expect(await api.events("m0609", null, 50, 100)).toEqual({ ok: true, page });
    expect(await api.audit("m0609", 100, 0)).toEqual({ ok: true, page });
    expect(seen.map((s) => [s.path, s.query])).toEqual([
      ["/api/v1/events", { robot: "m0609", kind: "write", limit: "100", offset: "0" }],
      ["/api/v1/events", { robot: "m0609", limit: "50", offset: "100" }],
      ["/api/v1/audit", { robot: "m0609", limit: "100", offset: "0" }],
    ]);
    const refused = service(403, { detail: { reason: "operators only", field: null } });
    expect(await refused.api.audit("m0609", 100, 0)).toEqual({ ok: false, status: 403, reason: "operators only" });
  });

  it("logs in with a JSON body and reads who is logged in", async () => {
    const { api, seen } = service(200, { user: { name: "op", role: "operator" }, token: "t" });
    expect((await api.login("op", "pw")).status).toBe(200);
    expect(seen[0]).toMatchObject({ method: "POST", path: "/api/v1/auth/login", contentType: "application/json", body: { username: "op", password: "pw" } });
    expect(await api.me()).toEqual({ name: "op", role: "operator" });
    expect(await service(200, { user: null }).api.me()).toBeNull();
    const out = service(200, { user: null });
    await out.api.logout();
    expect(out.seen[0]).toMatchObject({ method: "POST", path: "/api/v1/auth/logout", contentType: "application/json" });
  });
});

describe("errorReason", () => {
  it("reads the service's reason, a plain detail, or falls back to the status", () => {
    expect(errorReason({ status: 422, body: { detail: { reason: "analog_output.0: out of range", field: "analog_output.0" } } })).toBe(
      "analog_output.0: out of range",
    );
    expect(errorReason({ status: 404, body: { detail: "Not Found" } })).toBe("Not Found");
    expect(errorReason({ status: 502, body: "Bad Gateway" })).toBe("HTTP 502");
    expect(errorReason({ status: 500, body: null })).toBe("HTTP 500");
  });
});

describe("CSV links", () => {
  it("name the robot and the filter", () => {
    expect(eventsCsvUrl("m0609", "flag")).toBe("/api/v1/events?robot=m0609&format=csv&limit=100000&kind=flag");
    expect(eventsCsvUrl("m0609", null)).toBe("/api/v1/events?robot=m0609&format=csv&limit=100000");
    expect(auditCsvUrl("m1013")).toBe("/api/v1/audit?robot=m1013&format=csv&limit=100000");
  });
});
