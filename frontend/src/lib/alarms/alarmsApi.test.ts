// The panel's alarm and tag-name calls: which request each sends (method, path, query, content
// type, body) and how it reads the answers. The service is stood in for by a fetch that records
// the request and answers as the service does (docs/api.md "Alarms", "Tag names"); the real
// service is exercised end to end in e2e/ (20-alarms).
import createClient from "openapi-fetch";
import { describe, expect, it } from "vitest";
import type { paths } from "../../generated/api";
import { alarmHistoryCsvUrl, AlarmsApi, tagsCsvUrl } from "./alarmsApi";

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
  const api = new AlarmsApi(createClient<paths, "application/json">({ baseUrl: "http://hmi.test", fetch }));
  return { api, seen };
}

const ALARM = { id: "left:emergency_stop", state: "active_acknowledged" };

describe("AlarmsApi", () => {
  it("acknowledges an alarm by its id (the colon encoded), with a comment or an empty JSON body", async () => {
    const { api, seen } = service(200, { alarm: ALARM, changed: true });
    expect(await api.ack("left:emergency_stop", "checked the cell")).toEqual({ ok: true, alarm: ALARM, changed: true });
    expect(await api.ack("left:emergency_stop", null)).toMatchObject({ ok: true });
    expect(seen).toMatchObject([
      { method: "POST", path: "/api/v1/alarms/left%3Aemergency_stop/ack", contentType: "application/json", body: { comment: "checked the cell" } },
      { method: "POST", path: "/api/v1/alarms/left%3Aemergency_stop/ack", contentType: "application/json", body: {} },
    ]);
  });

  it("says why an acknowledgement was refused", async () => {
    const { api } = service(409, { detail: { reason: "the alarm is normal: nothing to acknowledge", field: null } });
    expect(await api.ack("left:x", null)).toEqual({ ok: false, reason: "the alarm is normal: nothing to acknowledge" });
  });

  it("shelves with a reason and a duration, and unshelves", async () => {
    const { api, seen } = service(200, { alarm: ALARM, changed: true });
    await api.shelve("left:packet_loss", "cable being replaced", 3600);
    await api.unshelve("left:packet_loss");
    expect(seen).toMatchObject([
      { method: "POST", path: "/api/v1/alarms/left%3Apacket_loss/shelve", body: { reason: "cable being replaced", duration_s: 3600 } },
      { method: "POST", path: "/api/v1/alarms/left%3Apacket_loss/unshelve", contentType: "application/json" },
    ]);
  });

  it("asks the history with only the filters set", async () => {
    const { api, seen } = service(200, { items: [], total: 0 });
    expect(await api.history("left", { priority: "critical", since: 1000, until: null }, 100, 0)).toEqual({ ok: true, page: { items: [], total: 0 } });
    await api.history("left", { priority: null, since: null, until: null }, 50, 50);
    expect(seen.map((s) => s.query)).toEqual([
      { robot: "left", priority: "critical", since: "1000", limit: "100", offset: "0" },
      { robot: "left", limit: "50", offset: "50" },
    ]);
  });

  it("reads, replaces and imports tag names", async () => {
    const list = { robot: "left", points: [], tags: { "controlbox_do.2": "gripper close" } };
    const { api, seen } = service(200, list);
    expect(await api.tags("left")).toEqual({ ok: true, page: list });
    await api.putTags("left", { "controlbox_do.2": "gripper close" });
    await api.importTags("left", "key,label,name\ncontrolbox_do.2,DO 3,gripper close\n");
    expect(seen).toMatchObject([
      { method: "GET", path: "/api/v1/robots/left/tags" },
      { method: "PUT", path: "/api/v1/robots/left/tags", body: { tags: { "controlbox_do.2": "gripper close" } } },
      { method: "POST", path: "/api/v1/robots/left/tags/import", body: { csv: "key,label,name\ncontrolbox_do.2,DO 3,gripper close\n" } },
    ]);
  });

  it("says why an import was refused (the service names the line)", async () => {
    const { api } = service(422, { detail: { reason: "line 2: controlbox_do.3 is DO 4, not DO 3", field: "csv" } });
    expect(await api.importTags("left", "x")).toEqual({ ok: false, status: 422, reason: "line 2: controlbox_do.3 is DO 4, not DO 3" });
  });
});

describe("download links", () => {
  it("carry the history's filters and the CSV format", () => {
    const url = new URL(alarmHistoryCsvUrl("left", { priority: "high", since: 5, until: null }), "http://hmi.test");
    expect(url.pathname).toBe("/api/v1/alarms/history");
    expect(Object.fromEntries(url.searchParams)).toEqual({ format: "csv", robot: "left", priority: "high", since: "5" });
    expect(tagsCsvUrl("a b")).toBe("/api/v1/robots/a%20b/tags.csv");
  });
});
