// Issue 38, "Kiosk and phone" (items 10-12), in Chromium against the emulated cell:
// - the kiosk's tiles put each label right above its value, with an alarm as without (no value
//   nearer another cell's label than its own); its plots look back the service's 30 s; its flags'
//   and lamps' lights are 24 px at least at 1280 × 720; at 390 px no word is broken mid-word;
// - its cycle tile shows the last cycle, the mean of the last ten and the cycles of this shift,
//   as the service counts them;
// - a phone's panel (390 × 844) puts the alarms before the joints, folds the plots until asked
//   for, stacks the joint table within 370 px, and asks its stream for the fields it shows at
//   10 frames/s over a compressed WebSocket: the frames it receives carry only those.
import type { Page } from "@playwright/test";
import { expect, test } from "../support/fixtures";
import { settings } from "../support/settings";

const CYCLES_TIMEOUT_MS = 60_000;

/** The start of the shift in progress (ms), the starts being HH:MM in this machine's zone. */
function shiftStart(now_ms: number, starts: readonly string[]): number {
  let best = -Infinity;
  for (const back of [0, 1]) {
    for (const start of starts) {
      const [h, m] = start.split(":").map(Number);
      const at = new Date(now_ms);
      at.setDate(at.getDate() - back);
      at.setHours(h ?? 0, m ?? 0, 0, 0);
      if (at.getTime() <= now_ms) best = Math.max(best, at.getTime());
    }
  }
  return best;
}

/** Each tile cell's label and value boxes, and its value's nearest other label. */
async function cellGeometry(page: Page) {
  return page.getByTestId("kiosk-tiles").evaluate((root) => {
    const cells = Array.from(root.querySelectorAll<HTMLElement>(".tile__cell"));
    const labels = cells.map((c) => c.querySelector("dt")?.getBoundingClientRect() ?? null);
    return cells.map((cell, i) => {
      const dt = labels[i];
      const dd = cell.querySelector("dd")?.getBoundingClientRect() ?? null;
      if (dt == null || dd == null) return { ok: false, why: "no label or value" };
      const own = Math.max(0, dd.top - dt.bottom) + Math.abs(dd.left - dt.left);
      let nearestOther = Infinity;
      labels.forEach((other, j) => {
        if (j === i || other === null) return;
        const dx = Math.max(0, other.left - dd.right, dd.left - other.right);
        const dy = Math.max(0, other.top - dd.bottom, dd.top - other.bottom);
        nearestOther = Math.min(nearestOther, Math.hypot(dx, dy));
      });
      const above = dt.bottom <= dd.top + 1 && Math.abs(dt.left - dd.left) <= 1;
      return { ok: above && own < nearestOther, why: `label ${JSON.stringify(dt)} value ${JSON.stringify(dd)} own ${own} other ${nearestOther}` };
    });
  });
}

/** Words of the kiosk's visible text drawn on more than one line (a word broken mid-word). */
async function brokenWords(page: Page): Promise<string[]> {
  return page.evaluate(() => {
    const broken: string[] = [];
    const root = document.querySelector('[data-testid="kiosk"]');
    if (root === null) return ["no kiosk"];
    const walker = document.createTreeWalker(root, NodeFilter.SHOW_TEXT);
    const range = document.createRange();
    for (let node = walker.nextNode(); node !== null; node = walker.nextNode()) {
      const text = node.textContent ?? "";
      if (node.parentElement?.checkVisibility({ visibilityProperty: true }) !== true) continue;
      for (const match of text.matchAll(/\S+/g)) {
        range.setStart(node, match.index);
        range.setEnd(node, match.index + match[0].length);
        const lines = new Set(Array.from(range.getClientRects()).filter((r) => r.width > 0).map((r) => Math.round(r.top)));
        if (lines.size > 1) broken.push(match[0]);
      }
    }
    return broken;
  });
}

test("the kiosk's tiles: labels above values with and without an alarm, 30 s plots, 24 px lights, no broken word", async ({ page, robot }) => {
  await page.setViewportSize({ width: 1280, height: 720 });
  await page.goto(`/kiosk?robot=${settings.robotName}&tiles=joint_position,tcp_position`);
  await expect(page.getByTestId("tile-joint-position-0")).toHaveText(/\d/);
  await expect.poll(async () => (await cellGeometry(page)).filter((c) => !c.ok).map((c) => c.why), { timeout: 15_000 }).toEqual([]);
  // The plots look back the service's kiosk_plot_window_s (30 s), at least a cycle of 8 s.
  await expect(page.getByTestId("plot-joint-position-figure")).toHaveAttribute("data-window-ms", "30000");
  const lights = await page.evaluate(() =>
    Array.from(document.querySelectorAll<HTMLElement>(".kiosk .flag__light, .kiosk .lamp__light")).map((el) => {
      const r = el.getBoundingClientRect();
      return Math.min(r.width, r.height);
    }),
  );
  expect(lights.length).toBeGreaterThan(40);
  expect(Math.min(...lights)).toBeGreaterThanOrEqual(24 - 0.01);

  // An alarm: less room for the body, the labels still above their values.
  await robot.estop();
  await expect(page.getByTestId("kiosk-estop")).toBeVisible();
  await expect.poll(async () => (await cellGeometry(page)).filter((c) => !c.ok).map((c) => c.why), { timeout: 15_000 }).toEqual([]);

  await page.setViewportSize({ width: 390, height: 844 });
  await expect.poll(() => brokenWords(page), { timeout: 15_000 }).toEqual([]);
});

test("the kiosk's cycle tile: last, mean of ten, this shift's count as the service counts them", async ({ page, request }) => {
  await page.goto(`/kiosk?robot=${settings.robotName}&tiles=cycle_time`);
  const tile = page.getByTestId("tile-cycle-time");
  await expect(tile.locator("dt")).toHaveText(["last", "mean of 10", "this shift"]);
  await expect(page.getByTestId("tile-cycle-time-0")).toHaveText(/^\d+\.\d$/, { timeout: CYCLES_TIMEOUT_MS });
  await expect(page.getByTestId("tile-cycle-time-1")).toHaveText(/^\d+\.\d$/);
  // The shift's count is the service's count from the shift's start: 06:00, 14:00 or 22:00 in the
  // plant's zone, which is this machine's own here (the service's time_zone is not set).
  const from_s = shiftStart(Date.now(), ["06:00", "14:00", "22:00"]) / 1000;
  await expect
    .poll(
      async () => {
        const answer = await request.get(`/api/v1/robots/${settings.robotName}/cycles`, { params: { limit: "1", last: "1", from: String(from_s) } });
        const count = ((await answer.json()) as { statistics: { count: number } }).statistics.count;
        const shown = await page.getByTestId("tile-cycle-time-2").textContent();
        return shown === String(count) && count >= 1 ? "same" : `shown ${shown}, counted ${count}`;
      },
      { timeout: CYCLES_TIMEOUT_MS },
    )
    .toBe("same");
});

test("a phone's panel: alarms first, plots folded, the joint table within 370 px, a stream of what it shows", async ({ browser }) => {
  const context = await browser.newContext({ viewport: { width: 390, height: 844 }, hasTouch: true, isMobile: true });
  const page = await context.newPage();
  try {
    const sent: string[] = [];
    const received: string[] = [];
    page.on("websocket", (ws) => {
      ws.on("framesent", (f) => sent.push(String(f.payload)));
      ws.on("framereceived", (f) => received.push(String(f.payload)));
    });
    // The handshake's answer, as DevTools sees it (Playwright reports no upgrade's headers).
    const extensions: string[] = [];
    const cdp = await context.newCDPSession(page);
    await cdp.send("Network.enable");
    cdp.on("Network.webSocketHandshakeResponseReceived", (e) => {
      const headers = e.response.headers as Record<string, string>;
      const value = Object.entries(headers).find(([k]) => k.toLowerCase() === "sec-websocket-extensions")?.[1];
      extensions.push(value ?? "");
    });
    await page.goto(`/?robot=${settings.robotName}`);
    await expect(page.getByTestId("joint-table")).toBeVisible();
    // The alarms come first, right under the header.
    const tops = await page.evaluate(() => ["alarms", "joints", "tcp", "io"].map((id) => document.getElementById(id)?.getBoundingClientRect().top ?? NaN));
    expect(tops[0]).toBeLessThan(tops[1] ?? NaN);
    // The plots are folded until asked for.
    await expect(page.getByTestId("plot-joint-position")).toHaveCount(0);
    // The joint table stacked within 370 px, nothing scrolling sideways.
    const table = await page.getByTestId("joint-table").evaluate((t) => ({ width: t.getBoundingClientRect().width, scroll: t.scrollWidth, right: t.getBoundingClientRect().right }));
    expect(table.width).toBeLessThanOrEqual(370);
    expect(table.scroll).toBeLessThanOrEqual(370);
    expect(table.right).toBeLessThanOrEqual(390);
    await expect(page.getByTestId("joint-table").locator('td[data-field="joint_position"]').first()).toHaveText(/\d/);

    // Its stream: asked for what it shows at 10 frames/s, and sent only that.
    await expect.poll(() => sent.map((s) => JSON.parse(s) as { type: string }).filter((m) => m.type === "subscribe").length, { timeout: 15_000 }).toBeGreaterThan(0);
    const subscribe = sent.map((s) => JSON.parse(s) as { type: string; fields: string[] | null; rate_hz: number | null }).filter((m) => m.type === "subscribe").at(-1);
    expect(subscribe?.rate_hz).toBe(10);
    expect(subscribe?.fields).toEqual(expect.arrayContaining(["robot_state", "emergency_stopped", "joint_position"]));
    expect(subscribe?.fields).not.toContain("tool_offset_position"); // shown nowhere on the panel
    const subscribedAt = received.findIndex((r) => r.includes('"type":"subscribed"'));
    await expect.poll(() => received.slice(received.findLastIndex((r) => r.includes('"type":"subscribed"')) + 1).filter((r) => r.includes('"type":"frames"')).length, { timeout: 15_000 }).toBeGreaterThan(5);
    expect(subscribedAt).toBeGreaterThanOrEqual(0);
    const lastAck = received.findLastIndex((r) => r.includes('"type":"subscribed"'));
    const ack = JSON.parse(received[lastAck] ?? "{}") as { fields: string[] };
    for (const text of received.slice(lastAck + 1)) {
      const message = JSON.parse(text) as { type: string; frames?: { frame: Record<string, unknown> }[] };
      if (message.type !== "frames") continue;
      for (const item of message.frames ?? []) {
        for (const key of Object.keys(item.frame)) expect(ack.fields.includes(key.replace(/_name$/, "")), key).toBe(true);
      }
    }
    // Compressed: the service agreed to permessage-deflate.
    expect(extensions.length).toBeGreaterThan(0);
    expect(extensions.every((h) => h.includes("permessage-deflate"))).toBe(true);

    // Opened, the plots draw.
    await page.getByTestId("phone-plots-open").first().click();
    await expect(page.getByTestId("plot-joint-position")).toBeVisible();
  } finally {
    await context.close();
  }
});
