// Scenario 15: a live plot's hover shows values with units; after a zoom, "Back to live" brings
// the moving window back (before, the plot stayed on the old range and went blank); a pan past
// the ring goes into the recording and "Back to live" comes back from it; the signal picker
// plots a field of another robot; a plot saves as PNG. By keyboard only (issues 13/14): Tab to
// a plot's "Zoom out", Enter until the view is in the recording, "Earlier", then "Back to live";
// the focused plotting area takes arrow keys and + / −.
import type { Page, Request } from "@playwright/test";
import { expect, framesFlow, test } from "../support/fixtures";
import { shownRange } from "../support/plotRange";
import { settings } from "../support/settings";

const PLOT = "plot-joint-position";

/**
 * Requests of the recording's ranges for this plot's field, counted from the page. The first is
 * the live window's start, asked once as the page opens (the ring is empty then: lib/plots/plotBackfill.ts).
 */
function historyRequests(page: Page): string[] {
  const seen: string[] = [];
  page.on("request", (r: Request) => {
    if (/\/api\/v1\/robots\/[^/]+\/history\?.*fields=joint_position(&|$)/.test(r.url())) seen.push(r.url());
  });
  return seen;
}

/**
 * Until the ring holds the whole live window (10 s of frames since the page opened): a zoom
 * into it stays on the ring then, where before it the window's start is the recording's.
 */
async function ringHoldsWindow(page: Page): Promise<void> {
  await framesFlow(page, 1050);
}

/** The focused element's test id. */
async function focused(page: Page): Promise<string | null> {
  return page.evaluate(() => document.activeElement?.getAttribute("data-testid") ?? null);
}

/** Tab (forwards) until the element with test id `id` has the focus; keyboard only. */
async function tabTo(page: Page, id: string): Promise<void> {
  for (let i = 0; i < 300; i++) {
    if ((await focused(page)) === id) return;
    await page.keyboard.press("Tab");
  }
  throw new Error(`${id} never had the focus in 300 presses of Tab`);
}

/** The x range the plot shows now (ms since the epoch). */
async function xRange(page: Page): Promise<[number, number]> {
  return shownRange(page.getByTestId(PLOT));
}

/** The newest time the plot has drawn (its first trace's last x). */
async function newestX(page: Page): Promise<number> {
  return page.getByTestId(PLOT).evaluate((el) => {
    const xs = (el as HTMLElement & { data?: { x?: unknown[] }[] }).data?.[0]?.x ?? [];
    return Number(xs[xs.length - 1] ?? Number.NaN);
  });
}

/**
 * The live window's x range once it is whole: the moving window is 10 s wide (its 200 buckets
 * of 50 ms, first to last sample), but just after the page opened it holds only what the ring
 * has received since, so this waits for that.
 */
async function wholeLiveWindow(page: Page): Promise<[number, number]> {
  let range: [number, number] = [Number.NaN, Number.NaN];
  await expect
    .poll(async () => {
      range = await xRange(page);
      return range[1] - range[0];
    }, { message: "the live window 10 s wide" })
    .toBeGreaterThan(9_800);
  expect(range[1] - range[0]).toBeLessThanOrEqual(10_000 + 1);
  return range;
}

/** The panel with the plot drawing live data: the plot, its box and the height of its middle. */
async function openLivePlot(page: Page) {
  await page.goto(`/?robot=${settings.robotName}`);
  const plot = page.getByTestId(PLOT);
  await expect.poll(async () => Number(await plot.getAttribute("data-points"))).toBeGreaterThan(0);
  await ringHoldsWindow(page);
  const box = (await plot.boundingBox())!;
  return { plot, box, y: box.y + box.height / 2 };
}

test("hover while live, zoom, and back to live", async ({ page }) => {
  const { plot, box, y } = await openLivePlot(page);

  // Pointing at the plot makes it interactive while it keeps streaming; hover names the unit.
  await page.mouse.move(box.x + box.width * 0.7, y);
  await expect(plot).toHaveAttribute("data-interactive", "true");
  await page.mouse.move(box.x + box.width * 0.72, y + 5);
  await expect(page.locator(`[data-testid="${PLOT}"] .hoverlayer .hovertext`).first()).toContainText("degree");
  await expect(plot).toHaveAttribute("data-paused", "false");

  // Zoom into a slice of the last seconds by dragging a box. (A slice older than the moving
  // window by the time the drag ends goes into the recording instead: on a busy machine the
  // picture the person drags on lags the data by seconds and the drag itself takes two, so the
  // slice is 2–3 s old on screen, far inside the 10 s window.)
  await page.mouse.move(box.x + box.width * 0.7, y);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width * 0.85, y + 20, { steps: 6 });
  await page.mouse.up();
  await expect(plot).toHaveAttribute("data-zoomed", "true");
  await expect(plot, "a zoom inside the moving window stays on the ring").toHaveAttribute("data-view", "ring");
  const zoomed = await xRange(page);
  // Held where the person put it while the plot appends newer samples.
  const newest = await newestX(page);
  await expect.poll(() => newestX(page), { message: "the zoomed plot appends newer samples" }).toBeGreaterThan(newest);
  expect(await xRange(page)).toEqual(zoomed);

  await page.getByTestId(`${PLOT}-live`).click();
  await expect(plot).toHaveAttribute("data-zoomed", "false");
  await expect(page.getByTestId(`${PLOT}-live`)).toHaveCount(0);
  // The moving window again: 10 s wide (once the ring holds that much), its end moving on with the data.
  await page.mouse.move(0, 0);
  const live1 = await wholeLiveWindow(page);
  expect(live1[1]).toBeGreaterThan(zoomed[1]);
  await expect.poll(async () => (await xRange(page))[1]).toBeGreaterThan(live1[1] + 500);
  expect(Number(await plot.getAttribute("data-points"))).toBeGreaterThan(100);
});

test("a pan past the ring shows the recording; back to live from there", async ({ page }) => {
  const { plot, box, y } = await openLivePlot(page);
  await page.mouse.move(box.x + box.width * 0.5, y);
  await expect(plot).toHaveAttribute("data-interactive", "true");
  // The pan tool (chosen once Plotly says so: a click landing as the live plot redraws its mode
  // bar may be lost, and a person would click again), then a drag to the right: the view moves
  // most of its width into the past.
  const dragmode = () => plot.evaluate((el) => (el as HTMLElement & { _fullLayout?: { dragmode?: string } })._fullLayout?.dragmode);
  await expect(async () => {
    if ((await dragmode()) !== "pan") await page.locator(`[data-testid="${PLOT}"] .modebar-btn[data-attr="dragmode"][data-val="pan"]`).click();
    expect(await dragmode()).toBe("pan");
  }).toPass();
  await page.mouse.move(box.x + box.width * 0.2, y);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width * 0.9, y, { steps: 8 });
  await page.mouse.up();
  await expect(plot).toHaveAttribute("data-view", "fixed");
  await expect(page.getByTestId(`${PLOT}-pause`)).toHaveCount(0); // a range of the past: nothing to pause
  await expect(page.getByTestId(`${PLOT}-window`)).toHaveValue("range");
  // Drawn from the recording: the range the pan reached, at least half its span (the drag was
  // 70 % of the plot's width) before the newest data of when it was made.
  await expect.poll(async () => Number(await plot.getAttribute("data-frames"))).toBeGreaterThan(0);
  const [from_s, to_s] = [Number(await plot.getAttribute("data-from")), Number(await plot.getAttribute("data-to"))];
  expect(to_s).toBeLessThan(Date.now() / 1000 - (to_s - from_s) / 2);
  // The pan tool is still chosen once the range has come (a person pans on).
  expect(await dragmode()).toBe("pan");
  const past = await xRange(page);
  await framesFlow(page, 100);
  expect(await xRange(page)).toEqual(past); // a range of the past stays put as the data moves on

  await page.getByTestId(`${PLOT}-live`).click();
  await expect(plot).toHaveAttribute("data-view", "ring");
  await expect(plot).toHaveAttribute("data-zoomed", "false");
  await expect(page.getByTestId(`${PLOT}-window`)).toHaveValue("10000");
  await page.mouse.move(0, 0);
  const live = await xRange(page);
  expect(live[1]).toBeGreaterThan(past[1]);
  await expect.poll(async () => (await xRange(page))[1]).toBeGreaterThan(live[1] + 500);
});

test("pause, zoom, resume: the plot is live again, not blank", async ({ page }) => {
  await page.goto(`/?robot=${settings.robotName}`);
  const plot = page.getByTestId(PLOT);
  await expect.poll(async () => Number(await plot.getAttribute("data-points"))).toBeGreaterThan(0);
  await ringHoldsWindow(page);
  await page.getByTestId(`${PLOT}-pause`).click();
  await expect(plot).toHaveAttribute("data-paused", "true");
  // Paused, the plot turns into Plotly's interactive plot once Plotly has come (it is loaded on
  // the first need): a drag before then lands on the picture, which has no zoom box.
  await expect(plot).toHaveAttribute("data-interactive", "true");
  const box = (await plot.boundingBox())!;
  const y = box.y + box.height / 2;
  // A zoom into the paused picture's newest seconds: what the ring holds (on a busy machine the
  // live window moves on seconds past the picture before the drag).
  await page.mouse.move(box.x + box.width * 0.85, y);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width * 0.95, y + 20, { steps: 6 });
  await page.mouse.up();
  await expect(plot).toHaveAttribute("data-zoomed", "true");
  await expect(page.getByTestId(`${PLOT}-figure`)).toHaveAttribute("data-view", "ring");
  await framesFlow(page, 200); // the live data moves on past the paused picture
  await page.getByTestId(`${PLOT}-pause`).click(); // Resume
  await expect(plot).toHaveAttribute("data-paused", "false");
  await expect(plot).toHaveAttribute("data-zoomed", "false");
  const live = await xRange(page);
  await expect.poll(async () => (await xRange(page))[1]).toBeGreaterThan(live[1] + 500);
});

test("the signal picker plots a field of another robot; a plot saves as PNG", async ({ page }) => {
  await page.goto(`/?robot=${settings.robotName}`);
  await page.getByTestId("picker-robot").selectOption(settings.robot2Name);
  await page.getByTestId("picker-field").selectOption("joint_motor_temperature");
  await page.getByTestId("picker-add").click();
  const pane = page.getByTestId("plot-custom-1-pane");
  await expect(pane).toHaveAttribute("data-robot", settings.robot2Name);
  await expect(pane).toContainText("[°C]");
  await expect.poll(async () => Number(await page.getByTestId("plot-custom-1").getAttribute("data-points"))).toBeGreaterThan(0);
  // The same signal of the same robot twice is refused with a reason.
  await page.getByTestId("picker-field").selectOption("joint_motor_temperature");
  await expect(page.getByTestId("picker-refusal")).toContainText("already");

  const download = page.waitForEvent("download");
  await page.getByTestId(`${PLOT}-png`).click();
  const file = await download;
  expect(file.suggestedFilename()).toMatch(/^joint-position-.*\.png$/);
});

test("by keyboard: zoom out and pan into the recording, then back to live", async ({ page }) => {
  const requests = historyRequests(page);
  await page.goto(`/?robot=${settings.robotName}`);
  const plot = page.getByTestId(PLOT);
  const figure = page.getByTestId(`${PLOT}-figure`);
  await expect.poll(async () => Number(await plot.getAttribute("data-points"))).toBeGreaterThan(0);
  await page.mouse.move(0, 0);
  await tabTo(page, `${PLOT}-zoomOut`);
  await expect(page.getByTestId(`${PLOT}-zoomOut`)).toHaveAccessibleName("Zoom out");
  // Zoom out until the view reaches before what the live window holds: the recording.
  for (let i = 0; i < 6 && (await figure.getAttribute("data-view")) !== "fixed"; i++) {
    await page.keyboard.press("Enter");
  }
  await expect(figure).toHaveAttribute("data-view", "fixed");
  await expect(plot).toHaveAttribute("data-view", "fixed");
  await expect.poll(() => requests.length).toBeGreaterThan(1); // beyond the live window's start
  await expect.poll(async () => Number(await plot.getAttribute("data-frames"))).toBeGreaterThan(0);
  const out_from = Number(await plot.getAttribute("data-from"));
  const out_to = Number(await plot.getAttribute("data-to"));
  expect(await focused(page)).toBe(`${PLOT}-zoomOut`); // the focus stays on the button

  // "Earlier": half a range back, fetched from the recording again.
  await page.keyboard.press("Tab");
  expect(await focused(page)).toBe(`${PLOT}-earlier`);
  const asked = requests.length;
  await page.keyboard.press("Enter");
  const half = (out_to - out_from) / 2;
  await expect.poll(async () => Number(await plot.getAttribute("data-to"))).toBeCloseTo(out_to - half, 1);
  expect(Number(await plot.getAttribute("data-from"))).toBeCloseTo(out_from - half, 1);
  await expect.poll(() => requests.length).toBeGreaterThan(asked);
  await expect(figure).toHaveAttribute("data-view", "fixed");

  // "Back to live" by keyboard.
  await tabTo(page, `${PLOT}-live`);
  await page.keyboard.press("Enter");
  await expect(figure).toHaveAttribute("data-view", "ring");
  // The button is gone once live: the focus is on Pause, drawn again, not lost to the page.
  await expect(page.getByTestId(`${PLOT}-pause`)).toBeFocused();
  await expect(plot).toHaveAttribute("data-zoomed", "false");
  await expect(page.getByTestId(`${PLOT}-window`)).toHaveValue("10000");
  const live = await xRange(page);
  await expect.poll(async () => (await xRange(page))[1]).toBeGreaterThan(live[1] + 500);
});

test("by keyboard on the plotting area: focus makes it interactive, ← goes back, → returns to live", async ({ page }) => {
  const requests = historyRequests(page);
  await page.goto(`/?robot=${settings.robotName}`);
  const plot = page.getByTestId(PLOT);
  const figure = page.getByTestId(`${PLOT}-figure`);
  await expect.poll(async () => Number(await plot.getAttribute("data-points"))).toBeGreaterThan(0);
  await page.mouse.move(0, 0);
  await expect(plot).toHaveAttribute("data-interactive", "false");
  await expect.poll(() => requests.length).toBe(1); // the live window's start, at the opening
  await ringHoldsWindow(page);
  await tabTo(page, PLOT);
  await expect(plot).toHaveAttribute("data-interactive", "true");
  // + zooms into the moving window (no request), → from there is live again.
  await page.keyboard.press("+");
  await expect(plot).toHaveAttribute("data-zoomed", "true");
  await expect(figure).toHaveAttribute("data-view", "ring");
  const zoomed = await xRange(page);
  expect(zoomed[1] - zoomed[0]).toBeLessThan(6_000);
  expect(requests).toHaveLength(1);
  // → onto now is live again: a press or more, as now moves on meanwhile (each moves 2.5 s on).
  for (let i = 0; i < 20 && (await plot.getAttribute("data-zoomed")) !== "false"; i++) {
    await page.keyboard.press("ArrowRight");
  }
  await expect(plot).toHaveAttribute("data-zoomed", "false");
  // ← reaches before the live window: the recording.
  await page.keyboard.press("ArrowLeft");
  await expect(figure).toHaveAttribute("data-view", "fixed");
  await expect.poll(() => requests.length).toBeGreaterThan(1);
  // → onto now is back to live (a press or more, as now moves on).
  for (let i = 0; i < 20 && (await figure.getAttribute("data-view")) !== "ring"; i++) {
    await page.keyboard.press("ArrowRight");
  }
  await expect(figure).toHaveAttribute("data-view", "ring");
  await expect(plot).toHaveAttribute("data-zoomed", "false");
  // Leaving the area by keyboard makes the live plot a static picture again (back: Tab goes on
  // into the mode bar's buttons, inside the area).
  await page.keyboard.press("Shift+Tab");
  await expect(plot).toHaveAttribute("data-interactive", "false");
});

test("on a touch screen the time-axis buttons are 44 × 44 px and a tap on Zoom out reaches the recording", async ({ browser }) => {
  const context = await browser.newContext({ viewport: { width: 390, height: 844 }, hasTouch: true, isMobile: true });
  const page = await context.newPage();
  try {
    await page.goto(`/?robot=${settings.robotName}`);
    // On a phone the plots are folded until opened (issue 38: alarms and state first).
    await page.getByTestId("phone-plots-open").first().tap();
    const plot = page.getByTestId(PLOT);
    await expect.poll(async () => Number(await plot.getAttribute("data-points"))).toBeGreaterThan(0);
    const buttons = page.getByRole("group", { name: "Joint position: time axis" }).getByRole("button");
    await expect(buttons).toHaveCount(4);
    for (const b of await buttons.all()) {
      await b.scrollIntoViewIfNeeded();
      const box = (await b.boundingBox())!;
      const name = (await b.getAttribute("aria-label")) ?? "";
      expect(box.width, name).toBeGreaterThanOrEqual(44);
      expect(box.height, name).toBeGreaterThanOrEqual(44);
    }
    await page.getByTestId(`${PLOT}-zoomOut`).tap();
    await expect(page.getByTestId(`${PLOT}-figure`)).toHaveAttribute("data-view", "fixed");
    // Onto now: live again (a tap or more, as now moves on meanwhile).
    const figure = page.getByTestId(`${PLOT}-figure`);
    for (let i = 0; i < 10 && (await figure.getAttribute("data-view")) !== "ring"; i++) await page.getByTestId(`${PLOT}-later`).tap();
    await expect(figure).toHaveAttribute("data-view", "ring");
    expect(await page.evaluate(() => document.documentElement.scrollWidth)).toBeLessThanOrEqual(390);
  } finally {
    await context.close();
  }
});
