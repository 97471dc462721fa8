// Issue 13, accessibility: axe-core finds nothing serious on the login and the panel, on the
// panel of an operator holding control, and on the kiosk, light and dark. (The 3D view's own
// audit is scenario 14's.) Audits of pages that redraw plots all the time are the suite's
// longest tests: numbered to start early, so that the shorter ones fill the workers around them.
import { ruleViolations, seriousViolations } from "../support/a11y";
import { expect, operatorWithControl, test } from "../support/fixtures";
import { settings } from "../support/settings";

for (const colorScheme of ["light", "dark"] as const) {
  test(`axe-core clean: login, panel and kiosk (${colorScheme})`, async ({ page }) => {
    // An audit of a page that redraws plots and numbers all the time is slow on a busy machine.
    test.setTimeout(300_000);
    await page.emulateMedia({ colorScheme });
    await page.goto("/");
    await expect(page.getByTestId("login-username")).toBeVisible();
    await expect(page.getByTestId("joint-table")).toHaveAttribute("data-frames", /[1-9]/);
    expect(await page.evaluate(() => document.documentElement.dataset.theme)).toBe(colorScheme);
    expect(await seriousViolations(page), "login and panel").toEqual([]);

    await operatorWithControl(page);
    expect(await seriousViolations(page), "panel with control").toEqual([]);

    await page.goto("/kiosk");
    await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", /.+/);
    expect(await seriousViolations(page), "kiosk").toEqual([]);
  });
}

// Issue 38 item 15: the plot markers' names hold the text they show (52 of them did not: the
// count), each page has one h1 and one main landmark, the fleet's landmarks are told apart.
const PAGE_RULES = ["page-has-heading-one", "landmark-one-main", "landmark-unique", "landmark-no-duplicate-main", "landmark-no-duplicate-banner"];

test("axe-core: plot markers named by what they show; one h1 and the landmarks on panel, kiosk and fleet", async ({ page, robot }) => {
  test.setTimeout(300_000);
  await page.goto(`/?robot=${settings.robotName}`);
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", /.+/);
  // Emergency stops and their resets: events (and alarms) on the plots' time axis.
  for (let i = 0; i < 2; i++) {
    await robot.estop();
    await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "EMERGENCY_STOP");
    await robot.reset();
    await expect(page.getByTestId("robot-state")).not.toHaveAttribute("data-state-name", "EMERGENCY_STOP");
  }
  const plot = "plot-joint-position";
  // A day's window: the cell's events so far share a marker or two, counts of two digits (axe
  // checks a name against its text from two characters on: "▲!22" was one's, its name not).
  await page.getByTestId(`${plot}-window`).selectOption(String(24 * 3_600_000));
  const markers = page.getByTestId(`${plot}-marker`);
  await expect(markers.first()).toBeVisible();
  await expect.poll(async () => Math.max(0, ...(await markers.locator("small").allTextContents()).map(Number))).toBeGreaterThanOrEqual(10);
  await expect(page.getByTestId(`${plot}-marker-key`)).toContainText("▲!");
  // Every marker's name starts with the count it shows, and says its events in words.
  for (const marker of await markers.all()) {
    const count = (await marker.locator("small").count()) > 0 ? await marker.locator("small").textContent() : null;
    const name = (await marker.getAttribute("aria-label")) ?? "";
    if (count !== null) expect(name.startsWith(`${count} events: `), name).toBe(true);
    expect(name).not.toMatch(/State [A-Z]+_|EMERGENCY_STOP|STANDALONE_/); // words, never a state's code
  }
  const figure = `[data-testid="${plot}-figure"]`;
  expect(await ruleViolations(page, ["label-content-name-mismatch", "button-name"], figure), "markers").toEqual([]);
  expect(await seriousViolations(page, figure), "markers").toEqual([]);
  expect(await ruleViolations(page, PAGE_RULES), "panel").toEqual([]);
  await expect(page.locator("h1")).toHaveCount(1);

  await page.goto(`/kiosk?robot=${settings.robotName}`);
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", /.+/);
  expect(await ruleViolations(page, PAGE_RULES), "kiosk").toEqual([]);
  await expect(page.locator("h1")).toHaveCount(1);

  await page.goto("/fleet");
  await expect(page.getByTestId("fleet-tile")).toHaveCount(2);
  expect(await ruleViolations(page, PAGE_RULES), "fleet").toEqual([]);
  expect(await seriousViolations(page), "fleet").toEqual([]);
  await expect(page.locator("h1")).toHaveCount(1);
});
