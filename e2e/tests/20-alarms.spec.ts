// Scenario 20: alarms end to end. An emergency stop on the robot raises the panel's alarm banner
// (the critical e-stop alarm, unacknowledged) within 1 s of the page receiving it; the alarm list has its row and an
// acknowledge button; acknowledging clears the unacknowledged mark in the list and the banner;
// the kiosk shows the same banner with nothing to press; a reset returns it to normal (it leaves
// the list, the history keeps every transition). Shelving (a reason is required) takes an alarm
// off both banners while it stays listed; unshelving brings it back.
import type { Page } from "@playwright/test";
import { expect, messageAt, noteMessage, operatorPanel, screenshot, test, watchMessages, type Service } from "../support/fixtures";
import { settings } from "../support/settings";

const ESTOP_ID = `${settings.robotName}:emergency_stop`;
const SAFE_OFF_ID = `${settings.robotName}:safe_off`;
/** The robot state SAFE_OFF (servo off), as the layout numbers it. */
const SAFE_OFF_STATE = 2;
/** The service's alarm_consequence_window_s (its default, as the e2e cell runs it). */
const CONSEQUENCE_WINDOW_S = 5;

/** Until no safety stop of the robot cleared within the consequence window: a SAFE_OFF then is
 *  an alarm of its own, not the designed-suppressed consequence of a stop's reset. */
async function outsideConsequenceWindow(service: Service): Promise<void> {
  const causes = new Set(["emergency_stop", "protective_stop"]);
  const answer = await service.api.get(`/api/v1/alarms/history?robot=${settings.robotName}&limit=50`);
  expect(answer.ok()).toBe(true);
  const { items } = (await answer.json()) as { items: { key: string; transition: string; time: number }[] };
  const cleared = items.filter((row) => causes.has(row.key) && row.transition === "cleared");
  const lastS = Math.max(0, ...cleared.map((row) => row.time)); // s since the epoch
  await expect.poll(() => Date.now() / 1000 - lastS, { timeout: 30_000 }).toBeGreaterThan(CONSEQUENCE_WINDOW_S + 1);
}

interface AlarmListed {
  readonly id: string;
  readonly state: string;
}

/** Acknowledge every unacknowledged alarm of the robot, so the test starts from a quiet list. */
async function acknowledgeAll(service: Service): Promise<void> {
  const answer = await service.api.get(`/api/v1/alarms?robot=${settings.robotName}`);
  expect(answer.status(), await answer.text()).toBe(200);
  const { items } = (await answer.json()) as { items: AlarmListed[] };
  for (const alarm of items) {
    if (alarm.state !== "active_unacknowledged" && alarm.state !== "returned_unacknowledged") continue;
    const ack = await service.api.post(`/api/v1/alarms/${encodeURIComponent(alarm.id)}/ack`, { data: { comment: "e2e: clean start" } });
    expect([200, 409], await ack.text()).toContain(ack.status());
  }
}

/** Note, in the page, when the banner first shows `alarmId` unacknowledged (it need not exist yet). */
async function noteBanner(page: Page, alarmId: string): Promise<void> {
  await page.evaluate((alarmId) => {
    const w = window as unknown as { __e2eBannerAt?: number };
    delete w.__e2eBannerAt;
    const seen = () => {
      const el = document.querySelector('[data-testid="alarm-banner"]');
      return el !== null && el.getAttribute("data-alarm") === alarmId && el.getAttribute("data-unacknowledged") === "true";
    };
    const observer = new MutationObserver(() => {
      if (w.__e2eBannerAt === undefined && seen()) {
        w.__e2eBannerAt = Date.now();
        observer.disconnect();
      }
    });
    observer.observe(document.body, { attributes: true, childList: true, subtree: true });
  }, alarmId);
}

test.afterEach(async ({ robot, operatorApi }) => {
  await robot.tryPost("/reset");
  await acknowledgeAll(operatorApi);
});

test("an emergency stop raises the alarm banner within 1 s and acknowledging clears the unacknowledged mark", async ({
  page,
  robot,
  operatorApi,
}, testInfo) => {
  // Generous: on a loaded machine the panel redraws its plots slowly (the one timing asserted,
  // the banner within 1 s, is issue 13's requirement, as scenario 02's badge: timed from the
  // page's receipt of the alarm, the page's own share of the way, which a busy machine cannot
  // stretch like the whole way from the press, a speed figure of bench/ noted here).
  test.setTimeout(120_000);
  await acknowledgeAll(operatorApi);
  await watchMessages(page);
  await operatorPanel(page);
  await expect(page.locator(`[data-testid="alarm-row"][data-alarm="${ESTOP_ID}"]`)).toHaveCount(0);
  await noteBanner(page, ESTOP_ID);
  await noteMessage(page, "alarm", new RegExp(`"kind":\\s*"alarm".*"id":\\s*"${ESTOP_ID}"`));

  const pressed_ms = Date.now();
  await robot.estop();
  const banner = page.getByTestId("alarm-banner");
  await expect(banner).toHaveAttribute("data-alarm", ESTOP_ID);
  await expect(banner).toHaveAttribute("data-priority", "critical");
  await expect(banner).toHaveAttribute("data-unacknowledged", "true");
  await expect(banner).toContainText("Emergency stop");
  // Measured in the page: when a person could first see it, from when the page received the
  // alarm; and, for the record, from the press (the request to the emulator included).
  const shown_at = (await page.evaluate(() => (window as unknown as { __e2eBannerAt?: number }).__e2eBannerAt))!;
  const received_at = (await messageAt(page, "alarm"))!;
  const seen_ms = shown_at - received_at;
  testInfo.annotations.push({
    type: "alarm banner shown (ms)",
    description: `after the page received the alarm: ${seen_ms}; after the press: ${shown_at - pressed_ms}`,
  });
  expect(received_at).toBeGreaterThanOrEqual(pressed_ms);
  expect(seen_ms).toBeGreaterThanOrEqual(0);
  expect(seen_ms).toBeLessThanOrEqual(1000);
  // The e-stop's pendant colour is red.
  await expect(banner).toHaveAttribute("data-colour", "red");

  const row = page.locator(`[data-testid="alarm-row"][data-alarm="${ESTOP_ID}"]`);
  await expect(row).toHaveAttribute("data-state", "active_unacknowledged");
  await expect(row).toHaveAttribute("data-unacknowledged", "true");
  await expect(row.getByTestId("alarm-unack-mark")).toBeVisible();
  // The audible cue sounds until muted.
  const mute = page.getByTestId("alarm-mute");
  await expect(mute).toHaveAttribute("data-sounding", "true");
  await mute.click();
  await expect(mute).toHaveAttribute("data-sounding", "false");
  await screenshot(page, testInfo, "alarm-banner");

  // The kiosk shows the same banner, and nothing to acknowledge it with.
  const kiosk = await page.context().newPage();
  await kiosk.goto("/kiosk");
  await expect(kiosk.getByTestId("alarm-banner")).toHaveAttribute("data-alarm", ESTOP_ID);
  await expect(kiosk.getByTestId("alarm-banner")).toContainText("Emergency stop");
  await expect(kiosk.getByTestId("alarm-ack")).toHaveCount(0);
  await screenshot(kiosk, testInfo, "kiosk-alarm-banner");

  await row.getByTestId("alarm-ack").click();
  await expect(row).toHaveAttribute("data-state", "active_acknowledged");
  await expect(row).toHaveAttribute("data-unacknowledged", "false");
  await expect(row.getByTestId("alarm-unack-mark")).toHaveCount(0);
  await expect(row.getByTestId("alarm-ack")).toHaveCount(0);
  await expect(row).toContainText(`acknowledged by ${settings.operator.name}`);
  await expect(banner).toHaveAttribute("data-unacknowledged", "false");
  await expect(kiosk.getByTestId("alarm-banner")).toHaveAttribute("data-unacknowledged", "false");

  // Reset: acknowledged and gone, so normal: out of the list and off both banners.
  await robot.reset();
  await expect(row).toHaveCount(0);
  await expect(page.locator(`[data-testid="alarm-banner"][data-alarm="${ESTOP_ID}"]`)).toHaveCount(0);
  await expect(kiosk.locator(`[data-testid="alarm-banner"][data-alarm="${ESTOP_ID}"]`)).toHaveCount(0);
  await kiosk.close();

  // The history keeps every transition, with who acknowledged.
  const history = (transition: string) =>
    page.locator(`[data-testid="alarm-history-row"][data-transition="${transition}"]`).filter({ hasText: "Emergency stop" }).first();
  await expect(history("activated")).toBeVisible();
  await expect(history("acknowledged")).toContainText(settings.operator.name);
  await expect(history("cleared")).toBeVisible();
});

test("a shelved alarm stays listed but leaves the banners; unshelved, it is back", async ({ page, robot, operatorApi }) => {
  // Generous: on a loaded machine the panel redraws its plots slowly (no timing is asserted here).
  test.setTimeout(120_000);
  await acknowledgeAll(operatorApi);
  await operatorPanel(page);
  // SAFE_OFF forced (no e-stop before it, so not its suppressed consequence): a high alarm, which
  // may be shelved for up to an hour (an emergency stop never is: e2e 40). The test before this
  // one cleared an e-stop seconds ago: a SAFE_OFF inside the consequence window after it is
  // rightly its suppressed consequence (no banner), so the window is let pass first.
  await outsideConsequenceWindow(operatorApi);
  await robot.setState(SAFE_OFF_STATE);
  const banner = page.getByTestId("alarm-banner");
  await expect(banner).toHaveAttribute("data-alarm", SAFE_OFF_ID);
  const row = page.locator(`[data-testid="alarm-row"][data-alarm="${SAFE_OFF_ID}"]`);
  const kiosk = await page.context().newPage();
  await kiosk.goto("/kiosk");
  await expect(kiosk.getByTestId("alarm-banner")).toHaveAttribute("data-alarm", SAFE_OFF_ID);

  // A reason is required.
  await row.getByTestId("alarm-shelve").click();
  await row.getByTestId("alarm-shelve-submit").click();
  await expect(row.getByTestId("alarm-shelve-error")).toContainText("why");
  await row.getByTestId("alarm-shelve-reason").fill("e2e: cell being inspected");
  await row.getByTestId("alarm-shelve-duration").selectOption({ label: "15 min" });
  await row.getByTestId("alarm-shelve-submit").click();
  await expect(row).toHaveAttribute("data-shelved", "true");
  await expect(row).toContainText("e2e: cell being inspected");
  await expect(page.locator(`[data-testid="alarm-banner"][data-alarm="${SAFE_OFF_ID}"]`)).toHaveCount(0);
  await expect(kiosk.locator(`[data-testid="alarm-banner"][data-alarm="${SAFE_OFF_ID}"]`)).toHaveCount(0);

  await row.getByTestId("alarm-unshelve").click();
  await expect(row).toHaveAttribute("data-shelved", "false");
  await expect(banner).toHaveAttribute("data-alarm", SAFE_OFF_ID);
  await expect(kiosk.getByTestId("alarm-banner")).toHaveAttribute("data-alarm", SAFE_OFF_ID);
  await kiosk.close();
});
