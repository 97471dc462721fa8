// The alarm banner as markup (react-dom/server, no DOM): what it shows for a set of current
// alarms, the data attributes the end-to-end tests read, and nothing for a quiet robot.
import { createElement } from "react";
import { renderToStaticMarkup } from "react-dom/server";
import { describe, expect, it } from "vitest";
import type { Alarm } from "../lib/alarms/alarms";
import { AlarmBanner } from "./AlarmBanner";

function alarm(key: string, over: Partial<Alarm>): Alarm {
  return {
    id: `left:${key}`, robot: "left", key, name: key, description: "", priority: "medium", priority_rank: 2,
    colour: "yellow", kind: "state", element: null, label: null, tag: null, unit: "", high: null, low: null,
    state: "active_unacknowledged", active: true, acknowledged: false, shelved: false, changed_at: 100,
    activated_at: 100, cleared_at: null, acknowledged_at: null, acknowledged_by: null, ack_comment: null,
    shelved_until: null, shelved_by: null, shelve_reason: null, value: null, message: null,
    ...over,
  };
}

const render = (alarms: readonly Alarm[], size: "panel" | "kiosk", listHref?: string) =>
  renderToStaticMarkup(createElement(AlarmBanner, { alarms, size, ...(listHref !== undefined ? { listHref } : {}) }));

describe("AlarmBanner", () => {
  it("shows the most urgent alarm in its colour, unacknowledged, with the count", () => {
    const estop = alarm("emergency_stop", { name: "Emergency stop", priority: "critical", priority_rank: 0, colour: "red" });
    const loss = alarm("packet_loss", { name: "Packet loss", message: "14 gaps in the last minute" });
    const html = render([loss, estop], "panel", "#alarms");
    expect(html).toContain('data-testid="alarm-banner"');
    expect(html).toContain('data-alarm="left:emergency_stop"');
    expect(html).toContain('data-priority="critical"');
    expect(html).toContain('data-colour="red"');
    expect(html).toContain('data-unacknowledged="true"');
    expect(html).toContain('data-count="2"');
    expect(html).toContain("Emergency stop");
    expect(html).toContain("+1 more · 2 alarms (2 unacknowledged)");
    expect(html).toContain('href="#alarms"');
    expect(html).toContain("background:#d32020");
  });

  it("says acknowledged once it is, and the kiosk's has no link", () => {
    const acked = alarm("protective_stop", { name: "Protective stop", priority: "high", priority_rank: 1, colour: "orange", state: "active_acknowledged", acknowledged: true });
    const html = render([acked], "kiosk");
    expect(html).toContain('data-unacknowledged="false"');
    expect(html).toContain("active, acknowledged");
    expect(html).toContain("alarm-banner--kiosk");
    expect(html).not.toContain("<a ");
    expect(html).not.toContain("alarm-banner-unack");
  });

  it("is absent when no alarm needs a person", () => {
    expect(render([], "panel")).toBe("");
    expect(render([alarm("x", { shelved: true })], "kiosk")).toBe("");
  });
});
