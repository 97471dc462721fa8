// Scenario 23 (issue 14): zoom back into history, see an e-stop marker, click it, export CSV of
// the view. The end-to-end service records from its start, so "5 minutes back" is shortened to
// what this run has recorded: the e-stop is caused here, and the "15 min" range (which holds it
// and everything recorded before it) is where the marker is found; the marker's click then jumps
// the plot a minute around it, and a zoom narrows that to a few seconds of the past.
import AxeBuilder from "@axe-core/playwright";
import { readFile } from "node:fs/promises";
import { expect, test } from "../support/fixtures";
import { settings } from "../support/settings";

test("history: an e-stop marker, a jump to it, a zoom, and the CSV of the view", async ({ page, robot }) => {
  // Many steps, an axe-core run and a download: generous on a busy machine.
  test.setTimeout(180_000);
  await page.goto(`/?robot=${settings.robotName}`);
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");
  const pressed_s = Date.now() / 1000;
  await robot.estop();
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "EMERGENCY_STOP");
  // A few seconds of the stop recorded, then the robot back.
  await page.waitForTimeout(3000);
  await robot.reset();
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "STANDALONE_STANDBY");
  await page.waitForTimeout(2000);

  const history = page.getByTestId("history");
  const plot = page.getByTestId("history-plot");
  await history.scrollIntoViewIfNeeded();
  await page.getByTestId("history-range-15m").click();
  await expect(page.getByTestId("history-range-15m")).toHaveAttribute("aria-pressed", "true");
  await expect(history).toHaveAttribute("data-window-mode", "live");

  // The stop's marker on the time axis (the newest, should an earlier test have stopped too).
  // Over 15 min, events seconds apart share a marker (its time is its first event's): the
  // program started by the test's set-up just before the stop may be in it.
  const marker = page.locator('[data-testid="history-marker"][aria-label*="EMERGENCY_STOP"]').last();
  await expect(marker).toBeVisible({ timeout: 15_000 });
  const first_s = Number(await marker.getAttribute("data-time"));
  expect(first_s).toBeGreaterThan(pressed_s - 30);
  expect(first_s).toBeLessThan(pressed_s + 5);

  // Markers and controls pass axe-core (nothing serious).
  const axe = await new AxeBuilder({ page }).include('[data-testid="history"]').analyze();
  expect(axe.violations.filter((v) => v.impact === "serious" || v.impact === "critical").map((v) => v.id)).toEqual([]);

  // Clicking it jumps the plot to a minute around it: a fixed range of the past.
  await marker.click();
  await expect(history).toHaveAttribute("data-window-mode", "history");
  await expect.poll(async () => Number(await plot.getAttribute("data-from"))).toBeCloseTo(first_s - 30, 1);
  expect(Number(await plot.getAttribute("data-to"))).toBeCloseTo(first_s + 30, 1);

  // At this zoom the stop has its own marker (with its alarm, at the same moment): on it again.
  const stopMarker = page.locator('[data-testid="history-marker"][aria-label*="EMERGENCY_STOP"]').last();
  await expect.poll(async () => Number(await stopMarker.getAttribute("data-time"))).toBeGreaterThan(pressed_s - 1);
  const stop_s = Number(await stopMarker.getAttribute("data-time"));
  expect(stop_s).toBeLessThan(pressed_s + 5);
  await stopMarker.click();
  await expect.poll(async () => Number(await plot.getAttribute("data-from"))).toBeCloseTo(stop_s - 30, 1);
  expect(Number(await plot.getAttribute("data-to"))).toBeCloseTo(stop_s + 30, 1);
  await expect.poll(async () => Number(await plot.getAttribute("data-frames"))).toBeGreaterThan(100);
  await expect(page.getByTestId("history-live")).toBeVisible();

  // Zoom into the middle of the view (a box drag): the narrower range is fetched and drawn.
  const box = (await plot.boundingBox())!;
  const y = box.y + box.height / 2;
  await page.mouse.move(box.x + box.width * 0.45, y);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width * 0.6, y + 20, { steps: 6 });
  await page.mouse.up();
  await expect
    .poll(async () => Number(await plot.getAttribute("data-to")) - Number(await plot.getAttribute("data-from")), { timeout: 10_000 })
    .toBeLessThan(30);
  const from_s = Number(await plot.getAttribute("data-from"));
  const to_s = Number(await plot.getAttribute("data-to"));
  expect(from_s).toBeGreaterThan(stop_s - 30);
  expect(to_s).toBeLessThan(stop_s + 30);
  await expect(history).toHaveAttribute("data-window-mode", "history");

  // Export the view as CSV: units in the header, every row inside the view.
  const downloading = page.waitForEvent("download");
  await page.getByTestId("history-export-csv").click();
  const download = await downloading;
  expect(download.suggestedFilename()).toMatch(new RegExp(`^${settings.robotName}_.*\\.csv$`));
  const text = await readFile((await download.path())!, "utf8");
  const lines = text.trim().split(/\r?\n/);
  // CSV cells, quoted or not (none of these holds a comma: names, units, times, numbers).
  const cells = (line: string) => line.split(",").map((c) => c.replace(/^"(.*)"$/, "$1"));
  const header = cells(lines[0]!);
  expect(header.slice(0, 3)).toEqual(["time", "seq", "joint_position.0 [degree]"]);
  expect(header).toHaveLength(2 + 6);
  const rows = lines.slice(1);
  expect(rows.length).toBeGreaterThan(10);
  // The export's range is the view's, to the millisecond of its link (`to` excluded).
  const times_s = rows.map((row) => Date.parse(cells(row)[0]!) / 1000);
  expect(times_s.every(Number.isFinite)).toBe(true);
  expect(Math.min(...times_s)).toBeGreaterThanOrEqual(Math.floor(from_s * 1000) / 1000 - 0.001);
  expect(Math.max(...times_s)).toBeLessThan(to_s + 0.001);

  // Back to live: the moving window again.
  await page.getByTestId("history-live").click();
  await expect(history).toHaveAttribute("data-window-mode", "live");
  await expect(page.getByTestId("history-live")).toHaveCount(0);
});

test("a paused live plot opens its range in the history plot", async ({ page }) => {
  await page.goto(`/?robot=${settings.robotName}`);
  const live = page.getByTestId("plot-joint-velocity");
  await expect.poll(async () => Number(await live.getAttribute("data-points"))).toBeGreaterThan(0);
  await page.getByTestId("plot-joint-velocity-pause").click();
  const paused_s = Date.now() / 1000;
  await page.getByTestId("plot-joint-velocity-history").click();
  const history = page.getByTestId("history");
  await expect(history).toHaveAttribute("data-window-mode", "history");
  await expect(page.getByTestId("history-plot-select")).toHaveValue("plot-joint-velocity");
  const plot = page.getByTestId("history-plot");
  // The live plot's window (10 s) up to the pause, from the recording.
  await expect.poll(async () => Number(await plot.getAttribute("data-to"))).toBeGreaterThan(paused_s - 2);
  const from_s = Number(await plot.getAttribute("data-from"));
  const to_s = Number(await plot.getAttribute("data-to"));
  expect(to_s - from_s).toBeCloseTo(10, 0);
  await expect.poll(async () => Number(await plot.getAttribute("data-frames"))).toBeGreaterThan(0);
});
