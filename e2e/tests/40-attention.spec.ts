// Scenario 40 (issue 38, "Safety of attention"): what the people around a cell must not miss.
// A kiosk shows the other robots' critical and unacknowledged alarms on a line readable from
// three metres (the second robot e-stopped through its emulator's control API: the first
// robot's kiosk names it and the alarm, in type of at least 32 px on a 1920 × 1080 screen). An
// emergency stop is never shelved (the panel offers no Shelve, the reason instead). And a
// session idles out on its person's actions, not on its page's polling: a private service with
// an 8 s lifetime keeps the session while the person types, then turns the open page to logged
// out at once with "Session expired: log in again", control released.
import { mkdtempSync } from "node:fs";
import path from "node:path";
import { expect, loginInPanel, operatorPanel, quietCell, screenshot, test, takeControl } from "../support/fixtures";
import { type Child, cobotHmi, freePort, runCobotHmi } from "../support/processes";
import { replaySettings } from "../support/replay";
import { settings } from "../support/settings";

const FIRST = settings.robotName;
const SECOND = settings.robot2Name;
/** The private service's session lifetime, s: short, but long enough for a loaded machine. */
const TTL_S = 8;

const children: Child[] = [];

test.afterAll(async () => {
  await Promise.all(children.map((child) => child.stop()));
});

test("another robot's emergency stop is on every kiosk, readable from three metres", async ({ page, robot, robot2, operatorApi }, testInfo) => {
  await quietCell([robot, robot2], operatorApi, "e2e 40: quiet start");
  await page.setViewportSize({ width: 1920, height: 1080 });
  await page.goto(`/kiosk?robot=${FIRST}`);
  await expect(page.getByTestId("kiosk-robot")).toHaveText(FIRST);
  await expect(page.getByTestId("kiosk-other-alarm")).toHaveCount(0);

  await robot2.estop();
  const line = page.getByTestId("kiosk-other-alarm");
  await expect(line).toHaveCount(1);
  await expect(line).toHaveAttribute("data-robot", SECOND);
  await expect(line).toContainText(`${SECOND}: Emergency stop`);
  await expect(line).toContainText("critical");
  await expect(line).toBeInViewport();
  const fontSize_px = await line.evaluate((el) => parseFloat(getComputedStyle(el).fontSize));
  expect(fontSize_px, "readable from 3 m on a 1080-line screen").toBeGreaterThanOrEqual(32);
  // The kiosk's own robot is fine: its own banner stays quiet, its state is its own.
  await expect(page.getByTestId("alarm-banner")).toHaveCount(0);
  await expect(page.getByTestId("kiosk")).toHaveAttribute("data-fits", "true");
  await screenshot(page, testInfo, "kiosk-other-robot-estop");

  // Reset and acknowledged: the line goes.
  await quietCell([robot, robot2], operatorApi, "e2e 40: reset");
  await expect(page.getByTestId("kiosk-other-alarm")).toHaveCount(0);
});

test("an emergency stop is never shelved: no Shelve, the reason instead", async ({ page, robot, robot2, operatorApi }) => {
  await quietCell([robot, robot2], operatorApi, "e2e 40: quiet start");
  await operatorPanel(page);
  await robot.estop();
  const row = page.locator(`[data-testid="alarm-row"][data-alarm="${FIRST}:emergency_stop"]`);
  await expect(row).toBeVisible();
  await expect(row.getByTestId("alarm-shelve")).toHaveCount(0);
  await expect(row.getByTestId("alarm-shelve-refused")).toHaveAttribute("title", /cannot be shelved/);
  await quietCell([robot, robot2], operatorApi, "e2e 40: reset");
});

/** A private service of one emulated robot with a short session lifetime (the cell's is 8 h). */
async function shortSessionService(): Promise<string> {
  const emulator = cobotHmi("e2e 40 emulator", ["emulator", "--host", replaySettings.robotHost, "--no-discovery"]);
  children.push(emulator);
  await emulator.waitFor("EtherNet/IP target on");
  const stateDir = mkdtempSync(path.join(settings.stateDir, "e2e40-"));
  await runCobotHmi("users add operator", ["users", "add", settings.operator.name, "--role", "operator", "--password-stdin", "--state-dir", stateDir], `${settings.operator.password}\n`);
  const port = await freePort(settings.httpHost);
  const service = cobotHmi("e2e 40 service", [
    "serve",
    "--robot", replaySettings.robotHost,
    "--robot-name", "solo",
    "--local-host", replaySettings.localHost,
    "--rpi-ms", String(settings.rpiMs),
    "--timeout-multiplier", String(settings.timeoutMultiplier),
    "--host", settings.httpHost,
    "--port", String(port),
    "--state-dir", stateDir,
    "--frontend-dir", settings.frontendDir,
    "--session-ttl-s", String(TTL_S),
  ]);
  children.push(service);
  const baseURL = `http://${settings.httpHost}:${port}`;
  await service.waitForHttp(`${baseURL}/readyz`, 200, 90_000, "e2e 40 service connected to its emulator");
  return baseURL;
}

test("a session idles out on its person's actions; the open page turns to logged out at once", async ({ page }, testInfo) => {
  test.setTimeout(180_000);
  const baseURL = await shortSessionService();
  await page.goto(`${baseURL}/?robot=solo`);
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  await loginInPanel(page, settings.operator);
  await takeControl(page);

  // The person types now and then for twice the lifetime: the session stays.
  const typing_ms = 2 * TTL_S * 1000;
  const started = Date.now();
  while (Date.now() - started < typing_ms) {
    await page.keyboard.press("Shift");
    await page.waitForTimeout(1000);
  }
  await expect(page.getByTestId("current-user")).toContainText(settings.operator.name);
  await expect(page.getByTestId("session-expired")).toHaveCount(0);
  const lastAction = Date.now();

  // Then nobody touches it; the page polls and streams on. It turns to logged out by itself.
  const expired = page.getByTestId("session-expired");
  await expect(expired).toHaveText("Session expired: log in again", { timeout: (TTL_S + 20) * 1000 });
  const after_s = (Date.now() - lastAction) / 1000;
  expect(after_s, "not before the lifetime after the person's last action").toBeGreaterThanOrEqual(TTL_S - 1);
  await expect(page.getByTestId("current-user")).toHaveCount(0);
  await expect(page.getByTestId("login-username")).toBeVisible();
  await screenshot(page, testInfo, "session-expired");
  // Control was released with it.
  const status = await page.request.get(`${baseURL}/api/v1/status`);
  expect(status.status()).toBe(200);
  expect(((await status.json()) as { control: { holder: unknown } }).control.holder).toBeNull();
  // Logging in again clears the message.
  await loginInPanel(page, settings.operator);
  await expect(expired).toHaveCount(0);
});
