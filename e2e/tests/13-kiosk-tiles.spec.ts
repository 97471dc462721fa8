// Scenario 13: the kiosk for three metres: large numeric tiles chosen in the URL with the
// layout's units, the state in plain words, a clock, connection health, no text under 18 px
// and still nothing that can write.
import type { Page } from "@playwright/test";
import { expect, screenshot, test } from "../support/fixtures";
import { settings } from "../support/settings";

/** Every piece of text on the page smaller than 18 px (HTML text and Plotly's SVG text). */
async function smallText(page: Page): Promise<string[]> {
  return page.evaluate(() => {
    const small: string[] = [];
    const root = document.querySelector('[data-testid="kiosk"]');
    if (root === null) return ["no kiosk"];
    const walker = document.createTreeWalker(root, NodeFilter.SHOW_TEXT);
    for (let node = walker.nextNode(); node !== null; node = walker.nextNode()) {
      const text = node.textContent?.trim() ?? "";
      const el = node.parentElement;
      if (text === "" || el === null) continue;
      const style = getComputedStyle(el);
      if (style.display === "none" || style.visibility === "hidden") continue;
      const size = parseFloat(style.fontSize);
      if (size < 18) small.push(`${el.tagName.toLowerCase()}.${String(el.getAttribute("class") ?? "")} "${text.slice(0, 20)}" ${size}px`);
    }
    return small;
  });
}

test("the kiosk shows the tiles its URL chooses, the state in words, a clock; no small text", async ({ page, robot }, testInfo) => {
  await page.goto(`/kiosk?robot=${settings.robotName}&tiles=joint_position,tcp_position,joint_motor_temperature`);
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  const tiles = page.getByTestId("kiosk-tiles").locator(".tile");
  await expect(tiles).toHaveCount(3);
  await expect(page.getByTestId("tile-joint-position")).toContainText("[degree]");
  await expect(page.getByTestId("tile-tcp-position")).toContainText("[mm]");
  await expect(page.getByTestId("tile-joint-motor-temperature")).toContainText("[°C]");

  // The numbers are the robot's: the temperatures change slowly, so the emulator's and the
  // tile's agree to the tile's one decimal within a little drift.
  const number = (text: string) => Number(text.replace("\u2212", "-"));
  await expect
    .poll(async () => {
      const status = await robot.status();
      const temps = status.frame.joint_motor_temperature as number[];
      const shown = await page.getByTestId("tile-joint-motor-temperature").locator("dd").allTextContents();
      return shown.length === 6 && shown.every((t, i) => Math.abs(number(t) - (temps[i] ?? NaN)) < 0.5);
    }, { message: "temperature tiles show the robot's values" })
    .toBe(true);
  const joints = await page.getByTestId("tile-joint-position").locator("dd").allTextContents();
  expect(joints).toHaveLength(6);
  for (const text of joints) expect(text).toMatch(/^\u2212?\d+\.\d$/);
  const tcp = await page.getByTestId("tile-tcp-position").locator("dt").allTextContents();
  expect(tcp).toHaveLength(3);

  // What the state means, in the layout's words, and a running clock.
  await expect(page.getByTestId("kiosk-state-words")).toHaveAttribute("data-state-title", "Standalone running");
  await expect(page.getByTestId("kiosk-state-words")).toContainText("The task program is being executed.");
  const clock = page.getByTestId("kiosk-clock");
  const first = await clock.textContent();
  await expect.poll(async () => await clock.textContent(), { timeout: 5_000 }).not.toBe(first);

  // Readable from three metres: nothing under 18 px, plot tick labels included.
  expect(await smallText(page)).toEqual([]);
  const tickSizes = await page.locator('[data-testid="kiosk"] svg text').evaluateAll((els) =>
    els.map((el) => parseFloat(getComputedStyle(el).fontSize)),
  );
  expect(tickSizes.length).toBeGreaterThan(0);
  expect(Math.min(...tickSizes)).toBeGreaterThanOrEqual(18);

  // And still nothing that can write.
  await expect(page.locator("button, input, select, textarea, form, [contenteditable='true'], [role='button']")).toHaveCount(0);
  await screenshot(page, testInfo, "kiosk-tiles");
});

test("a tile the robot does not report is named, not silently left out", async ({ page }) => {
  await page.goto("/kiosk?tiles=tcp_position,bogus_field,servo_on");
  await expect(page.getByTestId("tile-tcp-position")).toBeVisible();
  await expect(page.getByTestId("tile-unknown")).toContainText("bogus_field, servo_on");
});
