// Issue 38 (items 7, 9 and 13), tried as the people at the cell use it. A browser set to a zone
// far from the plant's still shows every time in the plant's (the service names it: the
// time_zone setting, here the host's own); the alarm history says an emergency stop's value in
// words, never the state's number; a search for "e-stop" finds the emergency stop; the kiosk says
// what the state means in a few words, not the manual's sentence, and has its one main landmark
// and its h1. An analog output shows its new type (name and unit) with the very render that says
// "confirmed", not up to 250 ms later.
import type { Page } from "@playwright/test";
import { expect, operatorWithControl, test } from "../support/fixtures";
import { settings } from "../support/settings";

/** The plant's zone: the cell's service has no time_zone set, so it is the host's, as here. */
const PLANT_ZONE = Intl.DateTimeFormat().resolvedOptions().timeZone || "UTC";
/** A browser far from the plant: its own zone would put every time hours off. */
const BROWSER_ZONE = PLANT_ZONE === "Pacific/Auckland" ? "America/New_York" : "Pacific/Auckland";

test.use({ timezoneId: BROWSER_ZONE });

/** "2026-11-27 07:21" of `ms` in `zone`. */
function minuteIn(ms: number, zone: string): string {
  const parts: Record<string, string> = {};
  const format = new Intl.DateTimeFormat("en-US", { timeZone: zone, hourCycle: "h23", year: "numeric", month: "2-digit", day: "2-digit", hour: "2-digit", minute: "2-digit" });
  for (const p of format.formatToParts(new Date(ms))) parts[p.type] = p.value;
  return `${parts.year}-${parts.month}-${parts.day} ${parts.hour === "24" ? "00" : parts.hour}:${parts.minute}`;
}

/** The minutes (plant's time) around `ms`: a row's time starts with one of them. */
function minutesAround(ms: number, zone: string): string[] {
  return [-60_000, 0, 60_000, 120_000].map((d) => minuteIn(ms + d, zone));
}

/**
 * In the page: when `testId` first shows `data-state` "idle" after "pending" (the write's answer
 * rendered) and when it first shows `data-type` `type` after that pending began (what a person
 * sees). Read them with `confirmTimes`.
 */
async function watchConfirmation(page: Page, testId: string, type: string): Promise<void> {
  await page.evaluate(
    ({ testId, type }) => {
      const w = window as unknown as { __e2eConfirm?: { pending?: number; idle?: number; type?: number } };
      const times: { pending?: number; idle?: number; type?: number } = {};
      w.__e2eConfirm = times;
      const el = document.querySelector(`[data-testid="${testId}"]`)!;
      const observer = new MutationObserver(() => {
        const now = performance.now();
        if (times.pending === undefined && el.getAttribute("data-state") === "pending") times.pending = now;
        if (times.pending === undefined) return;
        if (times.idle === undefined && el.getAttribute("data-state") === "idle") times.idle = now;
        if (times.type === undefined && el.getAttribute("data-type") === type) times.type = now;
        if (times.idle !== undefined && times.type !== undefined) observer.disconnect();
      });
      observer.observe(el, { attributes: true, attributeFilter: ["data-state", "data-type"] });
    },
    { testId, type },
  );
}

async function confirmTimes(page: Page): Promise<{ pending?: number; idle?: number; type?: number }> {
  return page.evaluate(() => (window as unknown as { __e2eConfirm?: { pending?: number; idle?: number; type?: number } }).__e2eConfirm ?? {});
}

async function stopAndReset(page: Page, robot: { estop(): Promise<unknown>; reset(): Promise<unknown> }): Promise<number> {
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", /.+/);
  const pressed_ms = Date.now();
  await robot.estop();
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "EMERGENCY_STOP");
  await robot.reset();
  await expect(page.getByTestId("robot-state")).not.toHaveAttribute("data-state-name", "EMERGENCY_STOP");
  return pressed_ms;
}

test("words and the plant's time on a browser in another zone: events, alarm history, kiosk", async ({ page, robot }) => {
  test.setTimeout(180_000);
  expect(minuteIn(Date.now(), BROWSER_ZONE)).not.toBe(minuteIn(Date.now(), PLANT_ZONE)); // the test can tell them apart
  await page.goto(`/?robot=${settings.robotName}`);
  const pressed_ms = await stopAndReset(page, robot);

  // The event log: "e-stop" finds the emergency stop, its time in the plant's zone.
  await page.getByTestId("events-search").fill("e-stop");
  const stops = page.getByTestId("events-table").locator("tbody tr").filter({ hasText: "Emergency stop" });
  await expect(stops.first()).toBeVisible();
  const time = (await stops.first().locator("td").first().textContent()) ?? "";
  expect(minutesAround(pressed_ms, PLANT_ZONE).some((m) => time.startsWith(m)), `${time} in ${PLANT_ZONE} near ${minuteIn(pressed_ms, PLANT_ZONE)}`).toBe(true);
  await page.getByTestId("events-search").fill("estop");
  await expect(page.getByTestId("events-table").locator("tbody tr").filter({ hasText: "Emergency stop" }).first()).toBeVisible();

  // The alarm history: the emergency stop's value in words, never its state number (0).
  const activated = page.locator('[data-testid="alarm-history-row"][data-transition="activated"]').filter({ hasText: "Emergency stop" }).first();
  await expect(activated).toBeVisible();
  const value = activated.locator("td").nth(5);
  await expect(value).toHaveText("Emergency stop");
  const historyTime = (await activated.locator("td").first().textContent()) ?? "";
  expect(minutesAround(pressed_ms, PLANT_ZONE).some((m) => historyTime.startsWith(m)), historyTime).toBe(true);

  // The kiosk: the plant's zone named, the state in a few words, one main landmark and one h1.
  await page.goto(`/kiosk?robot=${settings.robotName}`);
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", /.+/);
  const zone = page.getByTestId("kiosk-zone");
  if (PLANT_ZONE === "UTC" || PLANT_ZONE === "Etc/UTC") await expect(zone).toHaveText("UTC");
  else await expect(zone).toContainText(PLANT_ZONE);
  const clock = (await page.getByTestId("kiosk-clock").textContent()) ?? "";
  expect(minutesAround(Date.now() - 60_000, PLANT_ZONE).map((m) => m.slice(11)).some((m) => clock.startsWith(m)), clock).toBe(true);
  const words = page.getByTestId("kiosk-state-words");
  await expect(words).not.toBeEmpty();
  await expect(words).not.toContainText(/Teach Pendant|task program is being executed|is displayed for/);
  await expect(page.locator("main")).toHaveCount(1);
  await expect(page.locator("h1")).toHaveCount(1);
});

test("an analog output shows its new type with the render that says confirmed", async ({ page }) => {
  test.setTimeout(180_000);
  await operatorWithControl(page);
  const ao = page.getByTestId("ao-1");
  await expect(ao).toHaveAttribute("data-type", /current|voltage/);
  const lags_ms: number[] = [];
  // Three writes, each changing the type: current (4–20 mA) and voltage (0–10 V) in turn.
  for (let i = 0; i < 3; i++) {
    const voltage = (await ao.getAttribute("data-type")) === "current";
    const [type, name, setpoint] = voltage ? ["1", "voltage", "5"] : ["0", "current", "12"];
    await page.getByTestId("ao-1-type").selectOption(type);
    await page.getByTestId("ao-1-setpoint").fill(setpoint);
    await page.getByTestId("ao-1-set").click();
    await expect(page.getByTestId("confirm-dialog")).toBeVisible();
    await watchConfirmation(page, "ao-1", name);
    await page.getByTestId("confirm-yes").click();
    await expect(ao).toHaveAttribute("data-state", "idle");
    await expect(ao).toHaveAttribute("data-type", name);
    await expect(page.getByTestId("ao-1-reason")).toHaveCount(0);
    const times = await confirmTimes(page);
    expect(times.idle, "confirmed seen").toBeDefined();
    expect(times.type, "type seen").toBeDefined();
    lags_ms.push(times.type! - times.idle!);
  }
  // The same render (a frame published up to 250 ms later would show it that much after).
  for (const lag of lags_ms) expect(lag, `type shown ${lags_ms.join(", ")} ms after confirmed`).toBeLessThanOrEqual(40);
});
