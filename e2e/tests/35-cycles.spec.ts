// Issue 23: cycle timing, its kiosk tile and the searchable event log. The first robot's emulated program marks
// each cycle start on bit output register 63, the service's cycle trigger for it: the panel's
// cycle view shows the emulator's cycles (the last, the mean, min and max, the trend and the
// histogram, the newest cycles), the second robot says it has no trigger; the events of the log
// are searched by text and time range without logging in (anyone may view here).
import { expect, test } from "../support/fixtures";
import { settings } from "../support/settings";

/** Two cycle starts of the demo program (~8 s apart) and the poll, with slack for a busy machine. */
const CYCLES_TIMEOUT_MS = 60_000;

test("the cycle panel shows the emulator's cycles", async ({ page, request }) => {
  await page.goto(`/?robot=${settings.robotName}`);
  const view = page.getByTestId("cycle-view");
  await view.scrollIntoViewIfNeeded();
  await expect(page.getByTestId("cycle-trigger")).toContainText("rising edge of Register out 63");
  const last = page.getByTestId("cycle-last");
  await expect(last).toHaveText(/^\d+\.\d\d s$/, { timeout: CYCLES_TIMEOUT_MS });
  // What the panel shows is what the service measured.
  const answer = await request.get(`/api/v1/robots/${settings.robotName}/cycles`, { params: { last: "20" } });
  expect(answer.status()).toBe(200);
  const body = (await answer.json()) as { cycles: { duration_s: number }[]; statistics: { count: number } };
  expect(body.statistics.count).toBeGreaterThanOrEqual(1);
  const durations = body.cycles.map((c) => c.duration_s);
  // The demo program's cycle: seconds long, and every one about as long as the others.
  for (const d of durations) expect(d).toBeGreaterThan(1);
  await expect(page.getByTestId("cycle-mean")).toHaveText(/^\d+\.\d\d s$/);
  await expect(page.getByTestId("cycle-table").locator("tbody tr").first()).toContainText(" s");
  await expect(page.getByTestId("cycle-trend").locator(".main-svg").first()).toBeVisible();
  await expect(page.getByTestId("cycle-histogram").locator(".main-svg").first()).toBeVisible();
  const csv = await request.get(`/api/v1/robots/${settings.robotName}/cycles`, { params: { format: "csv" } });
  expect((await csv.text()).split(/\r?\n/)[0]).toBe("id,start,end,duration_s,interrupted,interruption");
  // Printed: the cycle statistics alone, without a control.
  await page.evaluate(() => {
    document.body.dataset.printSection = "cycles";
  });
  await page.emulateMedia({ media: "print" });
  await expect(page.getByTestId("cycle-last")).toBeVisible();
  await expect(view.getByRole("button", { name: "Print" })).toBeHidden();
  await expect(view.locator("button:visible")).toHaveCount(0);
  await expect(page.locator("#events")).toBeHidden();
  await page.emulateMedia({ media: "screen" });

  await page.goto(`/?robot=${settings.robot2Name}`);
  await page.getByTestId("cycle-no-trigger").scrollIntoViewIfNeeded();
  await expect(page.getByTestId("cycle-no-trigger")).toContainText("No cycle trigger");
});

test("a cycle across an emergency stop is shown apart and left out of the statistics (issue 38)", async ({ page, robot, request }) => {
  const cyclesOf = async () => {
    const answer = await request.get(`/api/v1/robots/${settings.robotName}/cycles`);
    expect(answer.status()).toBe(200);
    return (await answer.json()) as {
      cycles: { duration_s: number; interrupted: boolean; interruption: string | null }[];
      statistics: { interrupted: number };
      in_progress_since: number | null;
    };
  };
  await page.goto(`/?robot=${settings.robotName}`);
  await page.getByTestId("cycle-view").scrollIntoViewIfNeeded();
  // A cycle under way, then the e-stop, the reset and the program started again.
  await expect.poll(async () => (await cyclesOf()).in_progress_since, { timeout: CYCLES_TIMEOUT_MS }).not.toBeNull();
  await robot.estop();
  await expect.poll(async () => (await robot.status()).frame.robot_state_name).toBe("EMERGENCY_STOP");
  await robot.normalize();
  const apart = page.getByTestId("cycle-interrupted");
  await expect(apart).toContainText("Emergency stop", { timeout: CYCLES_TIMEOUT_MS });
  await expect(page.getByTestId("cycle-interrupted-note")).toContainText(/interrupted cycles?, left out of the statistics/);
  const body = await cyclesOf();
  const stopped = body.cycles.filter((c) => c.interruption === "Emergency stop");
  expect(stopped.length).toBeGreaterThanOrEqual(1);
  expect(body.statistics.interrupted).toBeGreaterThanOrEqual(stopped.length);
  // Included on request: the statistics say so.
  await page.getByTestId("cycle-include-interrupted").check();
  await expect(page.getByTestId("cycle-interrupted-note")).toContainText("included in the statistics");
});

test("the event log is searched by text and time range without a login", async ({ page }) => {
  await page.goto(`/?robot=${settings.robotName}`);
  const table = page.getByTestId("events-table");
  await table.scrollIntoViewIfNeeded();
  // The log, not only the live events since the page opened.
  await expect(page.locator("#events .table-view__source")).toContainText("in the log");
  // The robot entered STANDALONE_RUNNING when the cell started: its state event is in the log.
  await page.getByTestId("events-search").fill("STANDALONE");
  await expect(page.locator("#events .table-view__source")).toContainText("matching");
  const rows = table.locator("tbody tr[data-kind]");
  await expect(rows.first()).toBeVisible();
  // Every row shown matches (case-insensitively), once the search's answer replaced the log's.
  await expect(rows.filter({ hasNotText: /standalone/i })).toHaveCount(0);
  await expect(rows.first()).toContainText(/standalone/i);
  await expect(page.getByTestId("events-csv")).toHaveAttribute("href", /q=STANDALONE/);
  // A range before the cell started: nothing in it.
  await page.getByTestId("events-to").fill("2001-01-01T00:00:00");
  await expect(table.locator("td.empty")).toHaveText("no events");
  await expect(page.locator("#events .table-view__source")).toContainText("0 of 0 matching");
});

test("the kiosk shows the last and the mean cycle time as a tile", async ({ page }) => {
  await page.goto(`/kiosk?robot=${settings.robotName}&tiles=cycle_time`);
  await expect(page.getByTestId("tile-cycle-time-0")).toHaveText(/^\d+\.\d$/, { timeout: CYCLES_TIMEOUT_MS });
  await expect(page.getByTestId("tile-cycle-time-1")).toHaveText(/^\d+\.\d$/);
});
