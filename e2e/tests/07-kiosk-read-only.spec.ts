// Scenario 7: the kiosk has no write control anywhere, and a viewer's API write is refused.
import { request as playwrightRequest } from "@playwright/test";
import { expect, screenshot, Service, test } from "../support/fixtures";
import { baseURL, settings } from "../support/settings";

test("the kiosk has no write control anywhere", async ({ page }, testInfo) => {
  const requests: string[] = [];
  page.on("request", (r) => requests.push(`${r.method()} ${new URL(r.url()).pathname}`));
  await page.goto("/kiosk");
  const kiosk = page.getByTestId("kiosk");
  await expect(kiosk).toBeVisible();
  const badge = page.getByTestId("robot-state");
  await expect(badge).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  // Readable from three metres.
  const fontSize_px = await badge.evaluate((el) => parseFloat(getComputedStyle(el).fontSize));
  expect(fontSize_px).toBeGreaterThanOrEqual(48);
  // Lamps, no toggles: the outputs are shown, never writable.
  await expect(page.getByTestId("do-3")).toHaveAttribute("data-state", /on|off/);

  // Nothing to press, type into or choose; no login; nothing marked as a write control.
  const controls = page.locator("button, input, select, textarea, form, [contenteditable='true'], [data-write], [role='button']");
  await expect(controls).toHaveCount(0);
  await expect(page.getByTestId("login-username")).toHaveCount(0);
  await expect(page.getByTestId("take-control")).toHaveCount(0);
  await expect(page.getByText(/log in|take control/i)).toHaveCount(0);

  // It only ever reads: no request but GET (the WebSocket's upgrade is a GET too), and never
  // to the login, control or command endpoints; checked once the page's requests have settled
  // (no request for half a second: the stream goes on over its WebSocket).
  await page.waitForLoadState("networkidle");
  expect(requests.filter((r) => !r.startsWith("GET "))).toEqual([]);
  expect(requests.filter((r) => /\/api\/v1\/(auth|control|command)/.test(r))).toEqual([]);

  await screenshot(page, testInfo, "kiosk");
});

test("a viewer's API writes are refused", async ({ robot }) => {
  const viewer = await Service.login(settings.viewer);
  try {
    const before = await robot.status();
    const take = await viewer.api.post("/api/v1/control/take");
    expect(take.status()).toBe(403);
    expect(JSON.stringify(await take.json())).toMatch(/operator|role/i);
    const write = await viewer.api.patch("/api/v1/command", { data: { controlbox_do: { 2: !before.frame.controlbox_do[2] } } });
    expect(write.status()).toBe(403);
    expect(((await write.json()) as { detail: { reason: string } }).detail.reason).toBeTruthy();
    const after = await robot.status();
    expect(after.plc_command.controlbox_do).toEqual(before.plc_command.controlbox_do);
    expect(after.frame.controlbox_do).toEqual(before.frame.controlbox_do);
  } finally {
    await viewer.dispose();
  }

  // Without any login at all: 401.
  const anonymous = await playwrightRequest.newContext({ baseURL });
  try {
    expect((await anonymous.patch("/api/v1/command", { data: { controlbox_do: { 2: true } } })).status()).toBe(401);
    expect((await anonymous.post("/api/v1/control/take")).status()).toBe(401);
  } finally {
    await anonymous.dispose();
  }
});
