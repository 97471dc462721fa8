// Scenario 33 (issue 24's smaller points): at 1366 × 768 the joint table's columns fit without a
// scroll inside it and the TCP table beside it keeps to its figures (no wide gaps); the register
// dialog says it is a register; the DO and tool DO buttons' accessible names hold their visible
// text (axe-core's label-content-name-mismatch); events read in words (the service's `text`);
// /fleet fills a 1920 px screen with a tile per robot showing its newest frame's age, its gaps,
// whether it is stale and its alarms (the most urgent in words, the counts), its "connected"
// at 4.5:1 or more, and axe-core finds nothing serious on it.
import AxeBuilder from "@axe-core/playwright";
import { seriousViolations } from "../support/a11y";
import { expect, operatorWithControl, screenshot, test, type Service } from "../support/fixtures";
import { settings } from "../support/settings";

/** Every unacknowledged alarm of `robot` acknowledged, so the scenarios after these start quiet. */
async function operatorApiAck(operatorApi: Service, robot: string): Promise<void> {
  const ack = await operatorApi.api.post("/api/v1/alarms/ack", { data: { robot, comment: "e2e 33" } });
  expect(ack.status(), await ack.text()).toBe(200);
}

test("at 1366 × 768 the joint table fits its columns and the TCP table has no wide gaps", async ({ page }, testInfo) => {
  await page.setViewportSize({ width: 1366, height: 768 });
  await page.goto("/");
  const joints = page.getByTestId("joint-table");
  await expect(joints).toHaveAttribute("data-frames", /[1-9]/);
  const sizes = await page.evaluate(() => {
    const joint = document.querySelector('[data-testid="joint-table"]')!;
    const tcp = document.querySelector<HTMLTableElement>('[data-testid="tcp-readout"]')!;
    const scroller = joint.closest(".readout-scroll")!;
    // The TCP table's widest gap: a value cell's width less its text's.
    let gap = 0;
    for (const cell of Array.from(tcp.querySelectorAll("td"))) {
      const range = document.createRange();
      range.selectNodeContents(cell);
      const style = getComputedStyle(cell);
      const padding = parseFloat(style.paddingLeft) + parseFloat(style.paddingRight);
      gap = Math.max(gap, cell.getBoundingClientRect().width - padding - range.getBoundingClientRect().width);
    }
    return {
      scrollWidth: scroller.scrollWidth,
      clientWidth: scroller.clientWidth,
      jointTop: joint.getBoundingClientRect().top,
      tcpTop: tcp.getBoundingClientRect().top,
      gap,
      fontSize: parseFloat(getComputedStyle(tcp).fontSize),
    };
  });
  await screenshot(page, testInfo, "readouts-1366");
  expect(sizes.scrollWidth, "the joint table scrolls inside").toBeLessThanOrEqual(sizes.clientWidth + 1);
  // Side by side, and no cell of the TCP table much wider than its text (a value holds 8 figures).
  expect(Math.abs(sizes.jointTop - sizes.tcpTop)).toBeLessThan(2);
  expect(sizes.gap, "the TCP table's widest gap (px)").toBeLessThan(4 * sizes.fontSize);
});

test("the register dialog says it is a register; DO buttons are named by their visible text; events read in words", async ({ page, robot, operatorApi }) => {
  test.setTimeout(180_000);
  await operatorWithControl(page);
  // The register: asked as one, its number and state in the question.
  const confirmSetting = page.getByTestId("setting-confirm-registers");
  await confirmSetting.scrollIntoViewIfNeeded();
  if (!(await confirmSetting.isChecked())) await confirmSetting.check();
  const register = page.getByTestId("bit-in-5");
  const before = await register.getAttribute("data-state");
  await register.click();
  await expect(page.getByTestId("confirm-dialog")).toContainText(`Set bit input register 5 ${before === "on" ? "OFF" : "ON"}?`);
  await page.getByTestId("confirm-no").click();
  await expect(page.getByTestId("confirm-dialog")).toHaveCount(0);

  // Every DO and tool DO button: its accessible name holds what it shows.
  // (The rule checks elements named by aria-label: the registers' compact buttons, "Bit input
  // register 5 off" for a visible "5"; the DO buttons are named by their text itself.)
  const axe = await new AxeBuilder({ page }).setLegacyMode(true).include("#io").include("#registers").withRules(["label-content-name-mismatch"]).analyze();
  expect(axe.violations.map((v) => `${v.id}: ${v.nodes.map((n) => n.target.join(" ")).join(", ")}`)).toEqual([]);
  expect(axe.passes.some((r) => r.id === "label-content-name-mismatch"), "the rule ran and passed").toBe(true);
  const name = await page.getByTestId("do-1").evaluate((el) => el.getAttribute("aria-label"));
  expect(name).toBeNull();
  await expect(page.getByRole("button", { name: /^DO 1\b.*(ON|OFF)\b.*cmd (on|off)/ })).toHaveCount(1);

  // An emergency stop's events, in the service's words ("… flag set", never "… on on").
  try {
    await robot.estop();
    const events = page.getByTestId("events-table");
    await events.scrollIntoViewIfNeeded();
    await expect(events).toContainText("Emergency stopped flag set");
    await expect(events).toContainText("Robot state Emergency stop");
    await expect(events).not.toContainText(/\bon on\b/);
  } finally {
    await robot.normalize();
    await operatorApiAck(operatorApi, settings.robotName);
  }
});

test("/fleet fills a 1920 px screen and shows each robot's frame age, gaps, staleness and alarms", async ({ page, robot2, operatorApi }, testInfo) => {
  test.setTimeout(180_000);
  await page.setViewportSize({ width: 1920, height: 1080 });
  await page.goto("/fleet");
  const tiles = page.getByTestId("fleet-tile");
  await expect(tiles).toHaveCount(2);
  const first = page.locator(`[data-testid="fleet-tile"][data-robot="${settings.robotName}"]`);
  const second = page.locator(`[data-testid="fleet-tile"][data-robot="${settings.robot2Name}"]`);
  await expect(first.getByTestId("fleet-frame-age")).toHaveAttribute("data-stale", "false");
  await expect(first.getByTestId("fleet-frame-age")).toContainText(/\d+(\.\d)? (ms|s)/);
  await expect(first.getByTestId("fleet-gaps")).toContainText("in the last minute");
  await expect(first.getByTestId("fleet-gaps")).toHaveAttribute("data-gaps-per-min", /^\d+$/);
  await expect(first.getByTestId("fleet-alarm-counts")).toHaveText("none");

  // The tiles share the width: together at least 90 % of it.
  const widths = await tiles.evaluateAll((els) => els.map((el) => el.getBoundingClientRect().width));
  expect(widths.reduce((a, b) => a + b, 0)).toBeGreaterThan(0.9 * (1920 - 48 - 16));

  // "connected" at WCAG AA on its tile.
  const ratio = await first.getByTestId("fleet-connection").evaluate((el) => {
    const rgb = (css: string) => (css.match(/[\d.]+/g) ?? []).slice(0, 3).map(Number);
    const lum = (css: string) => {
      const [r, g, b] = rgb(css).map((v) => {
        const c = v / 255;
        return c <= 0.03928 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4;
      });
      return 0.2126 * r! + 0.7152 * g! + 0.0722 * b!;
    };
    const fg = lum(getComputedStyle(el).color);
    const bg = lum(getComputedStyle(el.closest('[data-testid="fleet-tile"]')!).backgroundColor);
    return (Math.max(fg, bg) + 0.05) / (Math.min(fg, bg) + 0.05);
  });
  expect(ratio).toBeGreaterThanOrEqual(4.5);
  expect(await seriousViolations(page), "fleet").toEqual([]);

  // The second robot's emergency stop: its most urgent alarm in words, and the counts.
  try {
    await robot2.estop();
    await expect(second.getByTestId("fleet-top-alarm")).toContainText("Emergency stop — critical, active, unacknowledged");
    await expect(second.getByTestId("fleet-alarm-counts")).toContainText("1 alarm (1 unacknowledged)");
    await expect(second.getByTestId("fleet-alarms")).toHaveAttribute("data-priority", "critical");
    await expect(first.getByTestId("fleet-alarm-counts")).toHaveText("none");
    await screenshot(page, testInfo, "fleet-1920");
    expect(await seriousViolations(page), "fleet with an alarm").toEqual([]);
  } finally {
    await robot2.normalize();
    await operatorApiAck(operatorApi, settings.robot2Name);
  }
});
