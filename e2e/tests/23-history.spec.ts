// Scenario 23 (issue 14), on the live plots themselves: zoom a live plot back 5 minutes into the
// recording, see the e-stop's marker on its time axis, click it (every plot of the panel jumps to
// a minute around it), zoom in, export the view as CSV, and back to live (every plot, linked on
// the panel's one time axis: issue 24). The end-to-end service
// records from its start; the e-stop is caused here, seconds before the zoom, so the 5 minutes
// back from now hold it. A second test: a live window fetches nothing after its start (asked
// once per plot as the page opens); a long window (15 min)
// moves with now from the recording; a custom range.
import type { Page, Request } from "@playwright/test";
import { readFile } from "node:fs/promises";
import { seriousViolations } from "../support/a11y";
import { expect, framesFlow, recorded, recordedUntil, test } from "../support/fixtures";
import { settings } from "../support/settings";

const PLOT = "plot-joint-position";

/** Requests of the recording (a range, or its events), counted from the page. */
function historyRequests(page: Page): string[] {
  const seen: string[] = [];
  page.on("request", (r: Request) => {
    if (/\/api\/v1\/robots\/[^/]+\/history(\?|\/events\?)/.test(r.url())) seen.push(r.url());
  });
  return seen;
}

/** The start of the x range Plotly shows now (s since the epoch). */
async function xStart_s(page: Page, id: string): Promise<number> {
  return page.getByTestId(id).evaluate((el) => {
    const v = (el as HTMLElement & { _fullLayout?: { xaxis?: { range?: unknown[] } } })._fullLayout?.xaxis?.range?.[0];
    // Numeric dates are local time shown as UTC (the plots' shift); text ones read as UTC.
    const shown_ms = typeof v === "number" ? v : new Date(String(v).replace(" ", "T") + "Z").getTime();
    return (shown_ms + new Date().getTimezoneOffset() * 60_000) / 1000;
  });
}

/** A `datetime-local` value (local time) of epoch seconds, as the page writes it. */
function localInput(time_s: number): string {
  const d = new Date(time_s * 1000 - new Date(time_s * 1000).getTimezoneOffset() * 60_000);
  return d.toISOString().slice(0, 19);
}

test("a live plot: zoom back into history, the e-stop's marker, every plot jumps to it, the CSV of the view, back to live", async ({
  page,
  robot,
  request,
}) => {
  // Many steps, an axe-core run and a download: generous on a busy machine.
  test.setTimeout(180_000);
  await page.goto(`/?robot=${settings.robotName}`);
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");
  const pressed_s = Date.now() / 1000;
  await robot.estop();
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "EMERGENCY_STOP");
  // A few seconds of the stop recorded, then the robot back, and that recorded too.
  await recordedUntil(request, pressed_s + 3, "3 s of the stop recorded");
  const reset_s = Date.now() / 1000;
  await robot.reset();
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "STANDALONE_STANDBY");
  await recordedUntil(request, reset_s + 1, "the reset recorded");

  const plot = page.getByTestId(PLOT);
  const figure = page.getByTestId(`${PLOT}-figure`);
  const other = page.getByTestId("plot-tcp-position");
  await expect.poll(async () => Number(await plot.getAttribute("data-points"))).toBeGreaterThan(0);
  await expect(plot).toHaveAttribute("data-view", "ring");

  // Zoom out with the plot's own button (each click doubles the width around the middle) until
  // the view reaches 5 minutes back, far past the 10 s the plot holds: the plot fetches that
  // range from the recording.
  const box = (await plot.boundingBox())!;
  await page.mouse.move(box.x + box.width * 0.5, box.y + box.height * 0.5);
  await expect(plot).toHaveAttribute("data-interactive", "true");
  const zoomOut = page.locator(`[data-testid="${PLOT}"] .modebar-btn[data-attr="zoom"][data-val="out"]`);
  const fiveMinutesBack_s = Date.now() / 1000 - 300;
  for (let i = 0; i < 12 && (await xStart_s(page, PLOT)) > fiveMinutesBack_s; i++) await zoomOut.click();
  expect(await xStart_s(page, PLOT)).toBeLessThan(fiveMinutesBack_s);
  await expect(plot).toHaveAttribute("data-view", "fixed");
  // The range drawn is the view's (the newest request's answer; those of earlier clicks dropped).
  const viewStart_s = await xStart_s(page, PLOT);
  await expect.poll(async () => Number(await plot.getAttribute("data-from"))).toBeCloseTo(viewStart_s, 0);
  // (At least the stop's 3 s at RPI 10 ms: the recording may have begun seconds before it.)
  await expect.poll(async () => Number(await plot.getAttribute("data-frames"))).toBeGreaterThan(300);
  await expect(page.getByTestId(`${PLOT}-live`)).toBeVisible();
  // The other plots followed (the panel's one time axis, issue 24).
  await expect(other).toHaveAttribute("data-view", "fixed");

  // The stop's marker on the time axis (the newest, should an earlier test have stopped too).
  // Over 5 minutes, events seconds apart share a marker (`data-time` its first event's,
  // `data-last` its last's): the program started by the test's set-up just before the stop,
  // and the reset after it, may be in it.
  const markers = page.locator(`[data-testid="${PLOT}-marker"][aria-label*="Robot state Emergency stop"]`);
  const marker = markers.last();
  await expect(marker).toBeVisible();
  const first_s = Number(await marker.getAttribute("data-time"));
  const last_s = Number(await marker.getAttribute("data-last"));
  expect(first_s).toBeLessThan(pressed_s + 5);
  expect(last_s).toBeGreaterThan(pressed_s - 1);

  // Markers, range and export links pass axe-core (nothing serious).
  expect(await seriousViolations(page, `[data-testid="${PLOT}-figure"]`)).toEqual([]);

  // Clicking it jumps the plots — this one and the others of the panel — to its events and half
  // a minute either side.
  await marker.click();
  for (const p of [plot, other]) {
    await expect(p).toHaveAttribute("data-view", "fixed");
    await expect.poll(async () => Number(await p.getAttribute("data-from"))).toBeCloseTo(first_s - 30, 1);
    expect(Number(await p.getAttribute("data-to"))).toBeGreaterThan(last_s + 30 - 0.05); // (or a newer last event)
  }

  // At this zoom the stop's marker (with its alarm, at the same moment) is its own or nearly:
  // on it again.
  const stop = markers.last();
  await expect.poll(async () => Number(await stop.getAttribute("data-last"))).toBeGreaterThan(pressed_s - 1);
  const stopFirst_s = Number(await stop.getAttribute("data-time"));
  const stopLast_s = Number(await stop.getAttribute("data-last"));
  expect(stopFirst_s).toBeLessThan(pressed_s + 5);
  await stop.click();
  await expect.poll(async () => Number(await plot.getAttribute("data-from"))).toBeCloseTo(stopFirst_s - 30, 1);
  // Its last event may be newer than when it was read (the newest answer brings the events
  // since: the alarm's acknowledgement, the robot's next states), never older.
  const jumpTo_s = Number(await plot.getAttribute("data-to"));
  expect(jumpTo_s).toBeGreaterThan(stopLast_s + 30 - 0.05);
  expect(jumpTo_s).toBeGreaterThan(pressed_s + 25);
  await expect.poll(async () => Number(await plot.getAttribute("data-frames"))).toBeGreaterThan(100);

  // Zoom into the middle of the view (a box drag): the narrower range is fetched and drawn.
  const box2 = (await plot.boundingBox())!;
  const y = box2.y + box2.height / 2;
  await page.mouse.move(box2.x + box2.width * 0.45, y);
  await page.mouse.down();
  await page.mouse.move(box2.x + box2.width * 0.6, y + 20, { steps: 6 });
  await page.mouse.up();
  const jumpWidth_s = jumpTo_s - (stopFirst_s - 30);
  await expect
    .poll(async () => Number(await plot.getAttribute("data-to")) - Number(await plot.getAttribute("data-from")))
    .toBeLessThan(jumpWidth_s / 2);
  const from_s = Number(await plot.getAttribute("data-from"));
  const to_s = Number(await plot.getAttribute("data-to"));
  expect(from_s).toBeGreaterThan(stopFirst_s - 30);
  expect(to_s).toBeLessThan(jumpTo_s);
  await expect(plot).toHaveAttribute("data-view", "fixed");

  // Export the view as CSV: named after the robot and the range, units in the header, rows
  // inside the view only.
  const downloading = page.waitForEvent("download");
  await page.getByTestId(`${PLOT}-export-csv`).click();
  const download = await downloading;
  const stamp = (t_s: number) => `${new Date(Math.floor(t_s) * 1000).toISOString().slice(0, 19).replace(/[-:]/g, "")}Z`;
  const fromStamps = `(${stamp(from_s)}|${stamp(from_s + 0.001)})`; // the link's 3 decimals may round up
  expect(download.suggestedFilename()).toMatch(new RegExp(`^${settings.robotName}_${fromStamps}_\\d{8}T\\d{6}Z\\.csv$`));
  const text = await readFile((await download.path())!, "utf8");
  const lines = text.trim().split(/\r?\n/);
  // CSV cells, quoted or not (none of these holds a comma: names, units, times, numbers).
  const cells = (line: string) => line.split(",").map((c) => c.replace(/^"(.*)"$/, "$1"));
  const header = cells(lines[0]!);
  // Times and counters first (docs/api.md "History"), then the plot's six elements with units.
  expect(header.slice(0, 2)).toEqual(["time", "seq"]);
  // Named as the screen labels them (J 1 is joint_position.J1), not by the API's 0-based keys.
  expect(header.filter((c) => c.startsWith("joint_position."))).toEqual([1, 2, 3, 4, 5, 6].map((j) => `joint_position.J${j} [degree]`));
  expect(header.filter((c) => !/^(time|seq|t2o_sequence)$/.test(c))).toHaveLength(6);
  const rows = lines.slice(1);
  expect(rows.length).toBeGreaterThan(10);
  // The export's range is the view's, to the millisecond of its link (`to` excluded).
  const times_s = rows.map((row) => Date.parse(cells(row)[0]!) / 1000);
  expect(times_s.every(Number.isFinite)).toBe(true);
  expect(Math.min(...times_s)).toBeGreaterThanOrEqual(Math.floor(from_s * 1000) / 1000 - 0.001);
  expect(Math.max(...times_s)).toBeLessThan(to_s + 0.001);

  // Back to live: the moving window of the ring again, its end moving on.
  await page.getByTestId(`${PLOT}-live`).click();
  await expect(plot).toHaveAttribute("data-view", "ring");
  await expect(figure).toHaveAttribute("data-view", "ring");
  await expect(page.getByTestId(`${PLOT}-live`)).toHaveCount(0);
  await expect(page.getByTestId(`${PLOT}-marker`)).toHaveCount(0);
  await expect.poll(async () => Number(await plot.getAttribute("data-points"))).toBeGreaterThan(100);
  // Every other plot of the panel with it (linked: issue 24).
  for (const id of ["plot-tcp-position", "plot-joint-velocity", "plot-external-force"]) {
    await expect(page.getByTestId(id)).toHaveAttribute("data-view", "ring");
  }
});

test("a live window fetches nothing; a 15 min window moves with now from the recording; a custom range", async ({ page, request }) => {
  test.setTimeout(120_000);
  const requests = historyRequests(page);
  await page.goto(`/?robot=${settings.robotName}`);
  const id = "plot-joint-velocity";
  const plot = page.getByTestId(id);
  await expect.poll(async () => Number(await plot.getAttribute("data-points"))).toBeGreaterThan(0);
  // Every plot on its live window, streaming: after its start, asked once per plot as the page
  // opens (an off-screen plot draws every 5 s: 6 s of frames), not one request of the recording.
  await framesFlow(page, 600);
  const opening = requests.length;
  await framesFlow(page, 200);
  expect(requests).toHaveLength(opening);

  // The long window: from the recording, moving with now (its end follows the newest frames).
  await page.getByTestId(`${id}-window`).selectOption(String(15 * 60_000));
  await expect(plot).toHaveAttribute("data-view", "moving");
  await expect.poll(async () => Number(await plot.getAttribute("data-frames"))).toBeGreaterThan(0);
  const from0 = Number(await plot.getAttribute("data-from"));
  const to0 = Number(await plot.getAttribute("data-to"));
  expect(to0 - from0).toBeCloseTo(900, 0);
  expect(Math.abs(to0 - Date.now() / 1000)).toBeLessThan(30);
  expect(requests.length).toBeGreaterThan(0);
  await expect(page.getByTestId(`${id}-live`)).toHaveCount(0); // it is live
  await expect(page.getByTestId(`${id}-range`)).toContainText("(live)");
  await expect.poll(async () => Number(await plot.getAttribute("data-to")), { timeout: 20_000 }).toBeGreaterThan(to0 + 1);

  // A custom range of the past: 10 s the service has recorded.
  let span = await recorded(request);
  await expect.poll(async () => (span = await recorded(request)).last - span.first, { message: "10 s recorded" }).toBeGreaterThan(11);
  const to_s = Math.floor(span.last);
  await page.getByTestId(`${id}-window`).selectOption("custom");
  await page.getByTestId(`${id}-custom-from`).fill(localInput(to_s - 10));
  await page.getByTestId(`${id}-custom-to`).fill(localInput(to_s));
  await page.getByTestId(`${id}-custom-apply`).click();
  await expect(plot).toHaveAttribute("data-view", "fixed");
  await expect.poll(async () => Number(await plot.getAttribute("data-from"))).toBe(to_s - 10);
  expect(Number(await plot.getAttribute("data-to"))).toBe(to_s);
  await expect.poll(async () => Number(await plot.getAttribute("data-frames"))).toBeGreaterThan(0);

  // A short window again: the ring, and no more requests.
  await page.getByTestId(`${id}-window`).selectOption("10000");
  await expect(plot).toHaveAttribute("data-view", "ring");
  const asked = requests.length;
  await framesFlow(page, 200);
  expect(requests).toHaveLength(asked);
});
