// Scenario 13: the kiosk for three metres: large numeric tiles chosen in the URL with the
// layout's units, the state in plain words, a clock, connection health, no text under 18 px
// and still nothing that can write.
import type { Page } from "@playwright/test";
import { expect, screenshot, test, type Service } from "../support/fixtures";
import { settings } from "../support/settings";

/**
 * Every piece of text on the page that a person can see and that is smaller than 18 px (HTML
 * text; the plots' text is measured apart). A text node counts as seen when it takes room on
 * screen (its range has a box) and its element is visible (no `display: none` or
 * `visibility: hidden` on it or above it, not fully transparent).
 */
async function smallText(page: Page): Promise<string[]> {
  return page.evaluate(() => {
    const small: string[] = [];
    const root = document.querySelector('[data-testid="kiosk"]');
    if (root === null) return ["no kiosk"];
    const walker = document.createTreeWalker(root, NodeFilter.SHOW_TEXT);
    const range = document.createRange();
    for (let node = walker.nextNode(); node !== null; node = walker.nextNode()) {
      const text = node.textContent?.trim() ?? "";
      const el = node.parentElement;
      if (text === "" || el === null) continue;
      if (!el.checkVisibility({ opacityProperty: true, visibilityProperty: true })) continue;
      range.selectNodeContents(node);
      const box = range.getBoundingClientRect();
      if (box.width === 0 || box.height === 0) continue;
      const size = parseFloat(getComputedStyle(el).fontSize);
      if (size < 18) small.push(`${el.tagName.toLowerCase()}.${String(el.getAttribute("class") ?? "")} "${text.slice(0, 20)}" ${size}px`);
    }
    return small;
  });
}

/** How many visible text nodes the kiosk has (so an empty page cannot pass the size check). */
async function textCount(page: Page): Promise<number> {
  return page.evaluate(() => {
    const root = document.querySelector('[data-testid="kiosk"]');
    if (root === null) return 0;
    const walker = document.createTreeWalker(root, NodeFilter.SHOW_TEXT);
    let n = 0;
    for (let node = walker.nextNode(); node !== null; node = walker.nextNode()) {
      if ((node.textContent?.trim() ?? "") !== "" && node.parentElement?.checkVisibility({ visibilityProperty: true }) === true) n++;
    }
    return n;
  });
}

/**
 * The kiosk's plots are canvas pictures (plots/canvasPlot.ts): their tick labels and titles are
 * drawn with the canvas' `fillText`, which this init script watches, keeping the size in px of
 * the font each text inside the kiosk was last drawn with (the pictures redraw ten times a
 * second). Call before the page loads.
 */
async function watchPlotText(page: Page): Promise<void> {
  await page.addInitScript(() => {
    const sizes: number[] = [];
    (window as unknown as { plotTextPx: number[] }).plotTextPx = sizes;
    const fillText = CanvasRenderingContext2D.prototype.fillText;
    CanvasRenderingContext2D.prototype.fillText = function (this: CanvasRenderingContext2D, ...args: Parameters<typeof fillText>) {
      if (this.canvas.closest('[data-testid="kiosk"]') !== null && String(args[0]).trim() !== "") {
        const px = /(\d+(?:\.\d+)?)px/.exec(this.font);
        sizes.push(px === null ? 0 : Number(px[1]));
        if (sizes.length > 500) sizes.splice(0, sizes.length - 500);
      }
      fillText.apply(this, args);
    };
  });
}

/** The sizes (px) of the newest texts the kiosk's plots drew (`watchPlotText`), and any SVG text's. */
async function plotTextSizes(page: Page): Promise<number[]> {
  return page.evaluate(() => [
    ...(window as unknown as { plotTextPx: number[] }).plotTextPx,
    ...Array.from(document.querySelectorAll('[data-testid="kiosk"] svg text'))
      .filter((el) => (el.textContent?.trim() ?? "") !== "")
      .map((el) => parseFloat(getComputedStyle(el).fontSize)),
  ]);
}

test("the kiosk shows the tiles its URL chooses, the state in words, a clock; no small text", async ({ page, robot }, testInfo) => {
  await watchPlotText(page);
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
  await expect(page.getByTestId("kiosk-state-words")).toContainText("Running its program");
  const clock = page.getByTestId("kiosk-clock");
  const first = await clock.textContent();
  await expect.poll(async () => await clock.textContent()).not.toBe(first);

  // Readable from three metres: nothing under 18 px, plot tick labels included.
  expect(await smallText(page)).toEqual([]);
  const tickSizes = await plotTextSizes(page);
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

test("no text under 18 px with an alarm active and the 3D view shown", async ({ page, robot, operatorApi }, testInfo) => {
  test.setTimeout(120_000);
  const estopAlarm = `${settings.robotName}:emergency_stop`;
  await robot.estop();
  try {
    await watchPlotText(page);
    await page.goto(`/kiosk?robot=${settings.robotName}&robot3d=1&tiles=joint_position,tcp_position,joint_motor_temperature`);
    await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
    // Everything an alarm adds is there: the stop in large letters and the alarm banner.
    await expect(page.getByTestId("kiosk-estop")).toBeVisible();
    const banner = page.getByTestId("alarm-banner");
    await expect(banner).toHaveAttribute("data-alarm", estopAlarm);
    await expect(banner).toContainText("Emergency stop");
    // The 3D view drew, with its title.
    const view = page.getByTestId("robot-3d");
    await view.scrollIntoViewIfNeeded();
    await expect.poll(async () => Number(await view.getAttribute("data-renders")), { message: "3D view drew" }).toBeGreaterThan(0);
    await expect(view).toContainText("M1013");
    await expect(page.getByTestId("kiosk-tiles").locator(".tile")).toHaveCount(3);
    // The plots drew their tick labels.
    await expect.poll(async () => (await plotTextSizes(page)).length, { message: "plots drew" }).toBeGreaterThan(0);

    // Every visible text node, the banner's, the stop's and the 3D view's included: 18 px or more.
    expect(await textCount(page)).toBeGreaterThan(20);
    expect(await smallText(page)).toEqual([]);
    expect(Math.min(...(await plotTextSizes(page)))).toBeGreaterThanOrEqual(18);
    await screenshot(page, testInfo, "kiosk-alarm-3d");
  } finally {
    await robot.tryPost("/reset");
    await acknowledge(operatorApi, estopAlarm);
  }
});

/** Acknowledge `alarmId` if it waits for it, so the scenarios after this one start quiet. */
async function acknowledge(service: Service, alarmId: string): Promise<void> {
  const ack = await service.api.post(`/api/v1/alarms/${encodeURIComponent(alarmId)}/ack`, { data: { comment: "e2e 13: kiosk text sizes" } });
  expect([200, 409], await ack.text()).toContain(ack.status());
}
