// Scenario 31 (issue 24): the panel's plots share one time axis and one cursor. A box zoom on
// the joint position plot zooms the joint velocity plot to the same range; "Back to live" on
// the velocity plot brings the position plot back; Ctrl + the mouse wheel zooms them together;
// a plot unlinked keeps its own range. Pointing at one plot shows, under every linked plot, the
// values of its signals at that time with their units (Shift + ← / → move that cursor).
// Plotly's "Double-click to zoom back out" notice never shows. A plot opened on a window fills
// it from the recording at once, not as the ring fills.
import type { Locator, Page } from "@playwright/test";
import { expect, framesFlow, recorded, test } from "../support/fixtures";
import { shownRange } from "../support/plotRange";
import { settings } from "../support/settings";

const POSITION = "plot-joint-position";
const VELOCITY = "plot-joint-velocity";

async function openPanel(page: Page) {
  await page.goto(`/?robot=${settings.robotName}`);
  const position = page.getByTestId(POSITION);
  const velocity = page.getByTestId(VELOCITY);
  for (const p of [position, velocity]) await expect.poll(async () => Number(await p.getAttribute("data-points"))).toBeGreaterThan(0);
  return { position, velocity };
}

/** How long a time the plot shows (ms): a zoom is drawn at the page's next paint, not at once. */
async function shownSpan(plot: Locator): Promise<number> {
  const [from, to] = await shownRange(plot);
  return to - from;
}

/** Both plots show about the same x range (each draws it in its own time: 50 ms of slack). */
async function sameRange(a: Locator, b: Locator): Promise<void> {
  await expect
    .poll(async () => {
      const [ra, rb] = [await shownRange(a), await shownRange(b)];
      return Math.max(Math.abs(ra[0] - rb[0]), Math.abs(ra[1] - rb[1]));
    }, { message: "the same time range on both plots" })
    .toBeLessThan(50);
}

test("zoom one plot, the others follow; back to live on any brings all back; an unlinked plot stays", async ({ page }) => {
  const { position, velocity } = await openPanel(page);
  await expect(velocity).toHaveAttribute("data-renderer", "canvas"); // nobody points at it: the canvas picture
  const box = (await position.boundingBox())!;
  const y = box.y + box.height / 2;
  await page.mouse.move(box.x + box.width * 0.5, y);
  await expect(position).toHaveAttribute("data-interactive", "true");
  // A box zoom on the position plot (a slice of its live window).
  await page.mouse.move(box.x + box.width * 0.4, y);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width * 0.7, y + 20, { steps: 6 });
  await page.mouse.up();
  await expect(position).toHaveAttribute("data-zoomed", "true");
  await expect(velocity).toHaveAttribute("data-zoomed", "true");
  await expect.poll(() => shownSpan(position), { message: "the box's slice shown" }).toBeLessThan(5_000);
  await sameRange(position, velocity);
  // Plotly's notice ("Double-click to zoom back out") would cover the header: never shown.
  await expect(page.locator(".plotly-notifier .notifier-note")).toHaveCount(0);

  // Back to live on the velocity plot: both live again.
  await page.getByTestId(`${VELOCITY}-live`).click();
  for (const p of [position, velocity]) await expect(p).toHaveAttribute("data-zoomed", "false");

  // Ctrl + the wheel over the velocity plot zooms in around the time under the pointer, both plots.
  const vbox = (await velocity.boundingBox())!;
  await page.mouse.move(vbox.x + vbox.width * 0.5, vbox.y + vbox.height / 2);
  await page.keyboard.down("Control");
  await page.mouse.wheel(0, -300);
  await page.keyboard.up("Control");
  await expect(velocity).toHaveAttribute("data-zoomed", "true");
  await expect(position).toHaveAttribute("data-zoomed", "true");
  await page.mouse.move(0, 0);
  // Three notches of 1.25 from 10 s: about 5 s (drawn when the busy page next paints).
  await expect.poll(() => shownSpan(velocity), { message: "the wheel's zoom shown" }).toBeLessThan(7_000);
  await sameRange(position, velocity);
  await page.getByTestId(`${POSITION}-live`).click();
  for (const p of [position, velocity]) await expect(p).toHaveAttribute("data-zoomed", "false");

  // Unlinked, the velocity plot keeps its own axis.
  await page.getByTestId(`${VELOCITY}-linked`).uncheck();
  await expect(page.getByTestId(`${VELOCITY}-figure`)).toHaveAttribute("data-linked", "false");
  await page.getByTestId(`${POSITION}-zoomIn`).click();
  await expect(position).toHaveAttribute("data-zoomed", "true");
  await framesFlow(page, 50);
  await expect(velocity).toHaveAttribute("data-zoomed", "false");
  // Linked again: it follows the next move.
  await page.getByTestId(`${VELOCITY}-linked`).check();
  await page.getByTestId(`${POSITION}-zoomIn`).click();
  await expect(velocity).toHaveAttribute("data-zoomed", "true");
  await sameRange(position, velocity);
});

test("one cursor: pointing at one plot shows every plot's values at that time, with units", async ({ page }) => {
  const { position } = await openPanel(page);
  const box = (await position.boundingBox())!;
  // Point at a moment the plot holds (just after opening, on a busy machine, part of the
  // window may still be empty: a value there reads "—"); each try moves the pointer a little.
  let tries = 0;
  await expect
    .poll(
      async () => {
        tries += 1;
        const x = box.x + box.width * (0.85 - 0.05 * (tries % 4));
        await page.mouse.move(x, box.y + box.height / 2 + (tries % 2) * 4);
        return (await page.getByTestId(`${POSITION}-cursor-0`).textContent()) ?? "";
      },
      { timeout: 60_000, message: "a value under the pointer" },
    )
    .toMatch(/^J ?1 −?\d[\d.]* degree$/);
  const readout = (id: string) => page.getByTestId(`${id}-cursor`);
  await expect(readout(POSITION)).toBeVisible();
  await expect(readout(VELOCITY)).toBeVisible();
  const time = Number(await readout(POSITION).getAttribute("data-time"));
  expect(Number.isFinite(time)).toBe(true);
  // The same moment under every linked plot (the TCP plots too), each signal with its unit.
  for (const id of [VELOCITY, "plot-tcp-position"]) {
    await expect.poll(async () => Number(await readout(id).getAttribute("data-time"))).toBe(time);
  }
  await expect(page.getByTestId(`${POSITION}-cursor-0`)).toHaveText(/^J ?1 −?\d[\d.]* degree$/);
  await expect(page.getByTestId(`${VELOCITY}-cursor-0`)).toHaveText(/^J ?1 −?\d[\d.]*( … −?\d[\d.]*)? degree\/s$/);
  await expect(page.getByTestId(`${VELOCITY}-cursor-5`)).toContainText("degree/s");
  // The pointer gone: no cursor anywhere.
  await page.mouse.move(0, 0);
  await expect(readout(VELOCITY)).toBeHidden();

  // By keyboard: the focused plotting area, Shift + → puts the cursor in the middle, then later.
  await page.getByTestId(VELOCITY).focus();
  await page.keyboard.press("Shift+ArrowRight");
  await expect(readout(POSITION)).toBeVisible();
  const first = Number(await readout(POSITION).getAttribute("data-time"));
  await page.keyboard.press("Shift+ArrowRight");
  await expect.poll(async () => Number(await readout(POSITION).getAttribute("data-time"))).toBeGreaterThan(first);
  await expect(page.getByTestId(`${POSITION}-cursor-2`)).toContainText("degree");
});

test("a plot opened on its window fills it from the recording at once", async ({ page, request }) => {
  // The recording holds more than a 30 s window before the page opens.
  await expect
    .poll(async () => Date.now() / 1000 - (await recorded(request)).first, { message: "35 s recorded", timeout: 60_000 })
    .toBeGreaterThan(35);
  await page.goto(`/?robot=${settings.robotName}`);
  const velocity = page.getByTestId(VELOCITY);
  await expect.poll(async () => Number(await velocity.getAttribute("data-points"))).toBeGreaterThan(0);
  // A 30 s window picked just after the page opened: the ring holds a few seconds of it.
  const picked_ms = await page.evaluate(() => Date.now());
  await page.getByTestId(`${VELOCITY}-window`).selectOption("30000");
  await expect(velocity).toHaveAttribute("data-renderer", "canvas");
  // The window's start is the recording's (from the ring alone it would start when the page
  // opened, and take 30 s to fill): drawn from 15 s and more before the pick.
  await expect
    .poll(async () => (await shownRange(velocity))[0], { message: "the window drawn from before the page opened" })
    .toBeLessThan(picked_ms - 15_000);
  const [from, to] = await shownRange(velocity);
  expect(to - from).toBeGreaterThan(25_000);
});

test("a window picked on one plot: every linked plot's picker shows it, an unlinked one keeps its own (issue 38)", async ({ page }) => {
  await openPanel(page);
  const picker = (id: string) => page.getByTestId(`${id}-window`);
  await picker(POSITION).selectOption("30000");
  for (const id of [VELOCITY, "plot-tcp-position"]) await expect(picker(id)).toHaveValue("30000");
  await picker(VELOCITY).selectOption("120000");
  for (const id of [POSITION, "plot-tcp-position"]) await expect(picker(id)).toHaveValue("120000");
  // Unlinked, the velocity plot's picker stays on its own window.
  await page.getByTestId(`${VELOCITY}-linked`).uncheck();
  await picker(POSITION).selectOption("10000");
  await expect(picker("plot-tcp-position")).toHaveValue("10000");
  await expect(picker(VELOCITY)).toHaveValue("120000");
});
