// Scenario 9: packet loss injected: the gap counter rises and the display stays live.
import { expect, test } from "../support/fixtures";

test("packet loss raises the gap counter and the display stays live", async ({ page, robot }, testInfo) => {
  await page.goto("/");
  const status = page.getByTestId("connection-status");
  const gaps = page.getByTestId("frame-gaps");
  await expect(status).toHaveAttribute("data-state", "connected");
  await expect(gaps).not.toHaveText("—");
  const before = Number(await gaps.getAttribute("data-gaps"));

  await robot.setFaults({ t2o_drop_percent: 20 });
  await expect.poll(async () => Number(await gaps.getAttribute("data-gaps")), { message: "gap counter rises" }).toBeGreaterThan(before);
  // Live all along: connected, not stale, frames still arriving.
  for (let i = 0; i < 10; i++) {
    expect(await status.getAttribute("data-state")).toBe("connected");
    expect(await page.getByTestId("robot-state").getAttribute("data-stale")).toBe("false");
    expect(Number(await page.getByTestId("frame-age").getAttribute("data-age-ms"))).toBeLessThan(1000);
    await page.waitForTimeout(300);
  }
  // The number a person reads has risen too.
  const after = Number(/\d+/.exec((await gaps.textContent()) ?? "")?.[0]);
  expect(after).toBeGreaterThan(before);
  testInfo.annotations.push({ type: "gaps", description: `${before} → ${after}` });
  await robot.clearFaults();
});
