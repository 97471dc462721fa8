// Scenario 8: the emulator is killed: the panel shows disconnected and greys its values within
// the connection timeout plus 1 s; the emulator restarts: the panel is live again, no reload.
import { emulatorProcess, expect, screenshot, test } from "../support/fixtures";
import { connectionTimeoutMs } from "../support/settings";

test("the panel survives the robot going away and coming back", async ({ page }, testInfo) => {
  await page.goto("/");
  const status = page.getByTestId("connection-status");
  const badge = page.getByTestId("robot-state");
  await expect(status).toHaveAttribute("data-state", "connected");
  await expect(badge).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");
  await expect(page.getByTestId("stale-banner")).toHaveCount(0);
  // A mark that a reload would wipe.
  await page.evaluate(() => ((window as unknown as { __e2eNoReload: boolean }).__e2eNoReload = true));

  const deadline_ms = connectionTimeoutMs + 1000;
  const killed_ms = Date.now();
  const pid = emulatorProcess.kill();
  await expect(status).toHaveAttribute("data-state", "disconnected", { timeout: deadline_ms });
  const shown_ms = Date.now() - killed_ms;
  testInfo.annotations.push({ type: `disconnected shown after (ms), deadline ${deadline_ms}`, description: String(shown_ms) });
  expect(shown_ms).toBeLessThanOrEqual(deadline_ms);
  // Greyed: the badge and the values are marked stale, and the banner says since when.
  await expect(status).toHaveText(/disconnected/);
  await expect(badge).toHaveAttribute("data-stale", "true");
  await expect(badge).toHaveClass(/is-stale/);
  await expect(page.getByTestId("panel")).toHaveAttribute("data-stale", "true");
  await expect(page.getByTestId("di-1")).toHaveCSS("filter", "grayscale(1)");
  await expect(page.getByTestId("stale-banner")).toContainText("since");
  await screenshot(page, testInfo, "panel-disconnected");

  const newPid = await emulatorProcess.restart();
  expect(newPid).not.toBe(pid);
  await expect(status).toHaveAttribute("data-state", "connected", { timeout: 30_000 });
  await expect(badge).toHaveAttribute("data-stale", "false");
  await expect(badge).not.toHaveText("");
  await expect(page.getByTestId("stale-banner")).toHaveCount(0);
  await expect(page.getByTestId("di-1")).not.toHaveCSS("filter", "grayscale(1)");
  // The freshly started robot initialises, then runs its program: live data again.
  await expect(badge).toHaveAttribute("data-state-name", "STANDALONE_RUNNING", { timeout: 15_000 });
  expect(await page.evaluate(() => (window as unknown as { __e2eNoReload?: boolean }).__e2eNoReload)).toBe(true);
  await screenshot(page, testInfo, "panel-reconnected");
});
