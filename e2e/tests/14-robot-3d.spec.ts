// Scenario 14: the 3D view draws each robot by its own model's kinematics and moves with it:
// two pictures of its canvas a moment apart differ while the program runs, and the view can be
// rotated and reset. On the kiosk it is optional and has no controls.
import type { Locator, Page } from "@playwright/test";
import { expect, screenshot, test } from "../support/fixtures";
import { settings } from "../support/settings";

async function shownView(page: Page): Promise<Locator> {
  const view = page.getByTestId("robot-3d");
  await view.scrollIntoViewIfNeeded();
  await expect.poll(async () => Number(await view.getAttribute("data-renders")), { message: "3D view drew" }).toBeGreaterThan(0);
  return view;
}

test("the 3D view renders the robot and follows it live", async ({ page }, testInfo) => {
  await page.goto(`/?robot=${settings.robotName}`);
  const view = await shownView(page);
  await expect(view).toHaveAttribute("data-arm", "M1013");
  const canvas = view.locator("canvas");
  await expect(canvas).toBeVisible();
  const before = await canvas.screenshot();
  // The demo program moves the arm: the picture changes without anyone touching it.
  await expect
    .poll(async () => Buffer.compare(await canvas.screenshot(), before) !== 0, { timeout: 10_000, message: "the robot moved on screen" })
    .toBe(true);
  const renders = Number(await view.getAttribute("data-renders"));
  await page.waitForTimeout(1000);
  expect(Number(await view.getAttribute("data-renders"))).toBeGreaterThan(renders);

  // Rotate by dragging, then reset: the home view comes back.
  const box = (await canvas.boundingBox())!;
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width / 2 + 200, box.y + box.height / 2 + 40, { steps: 8 });
  await page.mouse.up();
  await page.getByTestId("robot-3d-reset").click();
  await screenshot(page, testInfo, "robot-3d");
});

test("each robot is drawn as its own model", async ({ page }) => {
  await page.goto(`/?robot=${settings.robot2Name}`);
  const view = await shownView(page);
  // The model comes with the robot list (polled), once the service has read the identity.
  await expect(view).toHaveAttribute("data-arm", "M0609", { timeout: 20_000 });
});

test("the kiosk shows the 3D view when asked, without controls", async ({ page }) => {
  await page.goto(`/kiosk?robot=${settings.robot2Name}&robot3d=1&arm=M0609`);
  const view = await shownView(page);
  await expect(view).toHaveAttribute("data-arm", "M0609");
  await expect(page.locator("button, input, select, textarea")).toHaveCount(0);
});
