// Scenario 14: the 3D view draws each robot by its own model's kinematics and follows it: the
// picture changes while the program runs, it keeps drawing, the joint angles it draws are the
// robot's frame's, and the flange's path grows while the arm moves and shrinks to nothing while
// it stands still. The camera turns by dragging, by the arrow keys on the focused view and by its
// buttons; it zooms by the wheel, + and − and its buttons; reset returns the home view. On the
// kiosk the view is optional and has no controls.
//
// The view reports what it does as attributes of its figure (components/Robot3DView.tsx):
// data-renders, data-camera-azimuth-deg / -elevation-deg / -distance-mm, data-joints-deg,
// data-tcp-path-points, data-tcp-path-mm.
import type { Locator, Page } from "@playwright/test";
import { seriousViolations } from "../support/a11y";
import { expect, screenshot, test } from "../support/fixtures";
import { settings } from "../support/settings";

/** One press of a camera button or key turns the view by this much (lib/robot3d/orbitCamera.ts). */
const ROTATE_STEP_DEG = 15;
const ZOOM_STEP_FACTOR = 1.25;

async function shownView(page: Page): Promise<Locator> {
  const view = page.getByTestId("robot-3d");
  await view.scrollIntoViewIfNeeded();
  await expect.poll(async () => Number(await view.getAttribute("data-renders")), { message: "3D view drew" }).toBeGreaterThan(0);
  return view;
}

const numberOf = async (view: Locator, name: string) => Number(await view.getAttribute(name));

interface Camera {
  readonly azimuth_deg: number;
  readonly elevation_deg: number;
  readonly distance_mm: number;
}

/**
 * The camera the view reports, read in one go (a busy page answers each question slowly); the
 * test waits for the view's first report before reading it.
 */
async function cameraOf(view: Locator): Promise<Camera> {
  return view.evaluate((el) => ({
    azimuth_deg: Number(el.getAttribute("data-camera-azimuth-deg")),
    elevation_deg: Number(el.getAttribute("data-camera-elevation-deg")),
    distance_mm: Number(el.getAttribute("data-camera-distance-mm")),
  }));
}

/** Hold the arm at `joints_deg` and wait until the view draws the robot's own frame's angles. */
async function drawsHeldPose(view: Locator, robot: { post(path: string, body?: object): Promise<unknown>; status(): Promise<{ frame: Record<string, unknown> }> }, joints_deg: number[]): Promise<void> {
  await robot.post("/joints", { joint_position: joints_deg });
  let frame: number[] = [];
  await expect
    .poll(async () => (frame = (await robot.status()).frame.joint_position as number[]), { message: "robot holds the pose" })
    .toEqual(joints_deg.map((v) => expect.closeTo(v, 1)));
  await expect
    .poll(
      async () => {
        const drawn = ((await view.getAttribute("data-joints-deg")) ?? "").split(",").map(Number);
        return drawn.length === frame.length && drawn.every((v, i) => Math.abs(v - (frame[i] as number)) <= 0.06);
      },
      { message: `the view draws the frame's joint angles ${frame.join(", ")}` },
    )
    .toBe(true);
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
    .poll(async () => Buffer.compare(await canvas.screenshot(), before) !== 0, { message: "the robot moved on screen" })
    .toBe(true);
  // It keeps drawing.
  const renders = await numberOf(view, "data-renders");
  await expect.poll(() => numberOf(view, "data-renders"), { message: "the view draws again" }).toBeGreaterThan(renders + 5);
  // The flange's path is drawn behind it, a path of some length while the program runs.
  await expect.poll(() => numberOf(view, "data-tcp-path-points"), { message: "path has points" }).toBeGreaterThan(2);
  await expect.poll(() => numberOf(view, "data-tcp-path-mm"), { message: "path has a length" }).toBeGreaterThan(10);
  await screenshot(page, testInfo, "robot-3d");
});

test("the view draws the robot's joint angles, and the path grows while the arm moves", async ({ page, robot }) => {
  test.setTimeout(120_000);
  await page.goto(`/?robot=${settings.robotName}`);
  const view = await shownView(page);
  // Held still at one pose, then at another: the view draws each frame's angles.
  await drawsHeldPose(view, robot, [20, -15, 75, 10, 60, -25]);
  await drawsHeldPose(view, robot, [-35, 10, 95, -20, 45, 30]);
  const renders = await numberOf(view, "data-renders");
  // Standing still, the path of the last seconds shrinks to nothing (its points all in one place).
  await expect.poll(() => numberOf(view, "data-tcp-path-mm"), { timeout: 30_000, message: "no path while still" }).toBeLessThanOrEqual(1);
  expect(await numberOf(view, "data-tcp-path-points")).toBeGreaterThan(0);
  // The program moves it again: the path grows, and goes on growing.
  await robot.setProgram(true);
  await expect.poll(() => numberOf(view, "data-tcp-path-mm"), { timeout: 20_000, message: "path grows" }).toBeGreaterThan(5);
  const grown = await numberOf(view, "data-tcp-path-mm");
  await expect.poll(() => numberOf(view, "data-tcp-path-mm"), { timeout: 20_000, message: "path grows further" }).toBeGreaterThan(grown);
  await expect.poll(() => numberOf(view, "data-renders")).toBeGreaterThan(renders);
  // And the angles drawn move with the robot's frames: no longer the held pose.
  await expect
    .poll(async () => (await view.getAttribute("data-joints-deg")) !== "-35.0,10.0,95.0,-20.0,45.0,30.0", { message: "view follows the program" })
    .toBe(true);
});

test("the camera turns and zooms by mouse, keyboard and buttons; reset returns home", async ({ page }) => {
  test.setTimeout(120_000);
  await page.goto(`/?robot=${settings.robotName}`);
  const view = await shownView(page);
  await expect(view).toHaveAttribute("data-camera-distance-mm", /^\d+$/);
  const home = await cameraOf(view);
  const near = (a: number, b: number, slack: number) => Math.abs(a - b) <= slack;
  const resetHome = async (how: () => Promise<void>) => {
    await how();
    await expect.poll(() => cameraOf(view), { message: "home view again" }).toEqual(home);
  };

  // Drag: the view turns (the azimuth changes, the distance does not).
  const canvasHolder = view.getByTestId("robot-3d-canvas");
  const box = (await canvasHolder.boundingBox())!;
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.down();
  await page.mouse.move(box.x + box.width / 2 + 200, box.y + box.height / 2, { steps: 8 });
  await page.mouse.up();
  await expect.poll(async () => (await cameraOf(view)).azimuth_deg, { message: "drag turns the view" }).not.toBe(home.azimuth_deg);
  expect(near((await cameraOf(view)).distance_mm, home.distance_mm, 2)).toBe(true);
  // The wheel zooms in.
  await page.mouse.move(box.x + box.width / 2, box.y + box.height / 2);
  await page.mouse.wheel(0, -300);
  await expect.poll(async () => (await cameraOf(view)).distance_mm, { message: "wheel zooms in" }).toBeLessThan(home.distance_mm - 10);
  await resetHome(() => page.getByTestId("robot-3d-reset").click());

  // Keyboard: Tab from the reset button reaches the view, which shows its focus ring.
  await page.keyboard.press("Tab");
  await expect(canvasHolder).toBeFocused();
  await expect(canvasHolder).toHaveAttribute("aria-label", /arrow keys/);
  const outline = await canvasHolder.evaluate((el) => {
    const style = getComputedStyle(el);
    return { style: style.outlineStyle, width: parseFloat(style.outlineWidth) };
  });
  expect(outline.style).toBe("solid");
  expect(outline.width).toBeGreaterThanOrEqual(2);
  const scrollY = await page.evaluate(() => window.scrollY);
  await page.keyboard.press("ArrowLeft");
  await expect.poll(() => cameraOf(view), { message: "← turns left" }).toEqual({ ...home, azimuth_deg: home.azimuth_deg + ROTATE_STEP_DEG });
  await page.keyboard.press("ArrowUp");
  await expect
    .poll(() => cameraOf(view), { message: "↑ views from higher" })
    .toEqual({ ...home, azimuth_deg: home.azimuth_deg + ROTATE_STEP_DEG, elevation_deg: home.elevation_deg + ROTATE_STEP_DEG });
  expect(await page.evaluate(() => window.scrollY), "the arrows turn the view, not scroll the page").toBe(scrollY);
  await page.keyboard.press("+");
  await expect
    .poll(async () => near((await cameraOf(view)).distance_mm, home.distance_mm / ZOOM_STEP_FACTOR, 2), { message: "+ zooms in" })
    .toBe(true);
  await page.keyboard.press("-");
  await page.keyboard.press("-");
  await expect
    .poll(async () => near((await cameraOf(view)).distance_mm, home.distance_mm * ZOOM_STEP_FACTOR, 2), { message: "− zooms out" })
    .toBe(true);
  await page.keyboard.press("ArrowRight");
  await page.keyboard.press("ArrowDown");
  await page.keyboard.press("ArrowDown");
  await expect
    .poll(async () => {
      const c = await cameraOf(view);
      return [c.azimuth_deg, c.elevation_deg];
    }, { message: "→ and ↓ turn back and view from lower" })
    .toEqual([home.azimuth_deg, home.elevation_deg - ROTATE_STEP_DEG]);
  await resetHome(() => page.keyboard.press("0"));

  // Buttons, for touch screens too: each named for a screen reader.
  const button = (action: string) => page.getByTestId(`robot-3d-${action}`);
  await expect(button("rotate-left")).toHaveAccessibleName("Turn left");
  await button("rotate-right").click();
  await expect.poll(async () => (await cameraOf(view)).azimuth_deg, { message: "▶ turns right" }).toBe(home.azimuth_deg - ROTATE_STEP_DEG);
  await button("rotate-left").click();
  await button("rotate-left").click();
  await expect.poll(async () => (await cameraOf(view)).azimuth_deg, { message: "◀ turns left" }).toBe(home.azimuth_deg + ROTATE_STEP_DEG);
  await button("rotate-down").click();
  await expect.poll(async () => (await cameraOf(view)).elevation_deg, { message: "▼ views from lower" }).toBe(home.elevation_deg - ROTATE_STEP_DEG);
  await button("rotate-up").click();
  await button("rotate-up").click();
  await expect.poll(async () => (await cameraOf(view)).elevation_deg, { message: "▲ views from higher" }).toBe(home.elevation_deg + ROTATE_STEP_DEG);
  await button("zoom-in").click();
  await expect
    .poll(async () => near((await cameraOf(view)).distance_mm, home.distance_mm / ZOOM_STEP_FACTOR, 2), { message: "+ button zooms in" })
    .toBe(true);
  await button("zoom-out").click();
  await button("zoom-out").click();
  await expect
    .poll(async () => near((await cameraOf(view)).distance_mm, home.distance_mm * ZOOM_STEP_FACTOR, 2), { message: "− button zooms out" })
    .toBe(true);
  await resetHome(() => button("reset").click());
});

test("on a touch screen the view's buttons are at least 44 × 44 px", async ({ browser }) => {
  const context = await browser.newContext({ viewport: { width: 390, height: 844 }, hasTouch: true, isMobile: true });
  const page = await context.newPage();
  try {
    await page.goto(`/?robot=${settings.robotName}`);
    const view = await shownView(page);
    const buttons = view.locator("button");
    await expect(buttons).toHaveCount(7);
    for (const b of await buttons.all()) {
      const box = (await b.boundingBox())!;
      expect(box.width, await b.getAttribute("data-testid") ?? "").toBeGreaterThanOrEqual(44);
      expect(box.height, await b.getAttribute("data-testid") ?? "").toBeGreaterThanOrEqual(44);
    }
    // A tap turns the view, and the page keeps to the phone's width.
    const before = Number(await view.getAttribute("data-camera-azimuth-deg"));
    await page.getByTestId("robot-3d-rotate-left").tap();
    await expect.poll(() => numberOf(view, "data-camera-azimuth-deg")).toBe(before + ROTATE_STEP_DEG);
    expect(await page.evaluate(() => document.documentElement.scrollWidth)).toBeLessThanOrEqual(390);
  } finally {
    await context.close();
  }
});

for (const colorScheme of ["light", "dark"] as const) {
  test(`axe-core finds nothing serious in the 3D view, its controls or the kiosk's (${colorScheme})`, async ({ page }) => {
    test.setTimeout(180_000);
    await page.emulateMedia({ colorScheme });
    await page.goto(`/?robot=${settings.robotName}`);
    const view = await shownView(page);
    await expect(view).toHaveClass(new RegExp(`robot3d--${colorScheme}`));
    await expect(view.getByTestId("robot-3d-canvas")).toHaveAttribute("role", "application");
    expect(await seriousViolations(page, '[data-testid="robot-3d"]'), "panel").toEqual([]);
    await page.goto(`/kiosk?robot=${settings.robotName}&robot3d=1`);
    await shownView(page);
    expect(await seriousViolations(page, '[data-testid="robot-3d"]'), "kiosk").toEqual([]);
  });
}

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
  // Nothing to focus or press: a picture with a name.
  await expect(view.getByTestId("robot-3d-canvas")).not.toHaveAttribute("tabindex", /.*/);
  await expect(view.getByTestId("robot-3d-canvas")).toHaveAttribute("role", "img");
});
