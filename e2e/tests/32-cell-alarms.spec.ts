// Scenario 32 (issue 24): alarms as the cell uses them, in the panel. A panel open on one robot
// shows the other robot's alarms: an emergency stop of the second robot (its emulator's control
// API) marks it on the robot switcher and gives it a line in the banner naming it, and the mark
// opens its panel. "Acknowledge all shown" acknowledges every unacknowledged alarm of the list
// in one request, the service auditing each one; the SAFE_OFF that an e-stop's reset brings is
// listed as suppressed by design (a consequence of the e-stop), with nothing to acknowledge.
import type { Page } from "@playwright/test";
import { expect, loggedIn, quietCell, screenshot, test, type Service } from "../support/fixtures";
import { seriousViolations } from "../support/a11y";
import { settings } from "../support/settings";

const FIRST = settings.robotName;
/** The robot state SAFE_OFF (servo off), as the layout numbers it. */
const SAFE_OFF = 2;
const SECOND = settings.robot2Name;

interface AuditRow {
  readonly id: number;
  readonly action: string;
  readonly outcome: string;
  readonly user: string | null;
}

/** The first robot's newest audit rows. */
async function auditRows(operatorApi: Service): Promise<AuditRow[]> {
  const audit = await operatorApi.api.get(`/api/v1/audit?robot=${FIRST}&limit=200`);
  expect(audit.status(), await audit.text()).toBe(200);
  return ((await audit.json()) as { items: AuditRow[] }).items;
}

const mark = (page: Page, robot: string) => page.locator(`[data-testid="robot-alarm-mark"][data-robot="${robot}"]`);
const otherLine = (page: Page, robot: string) => page.locator(`[data-testid="alarm-banner-other"][data-robot="${robot}"]`);

test.afterEach(async ({ robot, robot2, operatorApi }) => {
  await quietCell([robot, robot2], operatorApi, "e2e 32: quiet start");
});

test("another robot's emergency stop marks the switcher and names the robot in the banner", async ({ page, robot, robot2, operatorApi }, testInfo) => {
  await quietCell([robot, robot2], operatorApi, "e2e 32: quiet start");
  await page.goto(`/?robot=${FIRST}`);
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  await expect(page.getByTestId("robot-alarm-mark")).toHaveCount(0);
  await expect(page.getByTestId("alarm-banner-other")).toHaveCount(0);

  await robot2.estop();
  // The mark on the switcher: the second robot, critical.
  await expect(mark(page, SECOND)).toBeVisible();
  await expect(mark(page, SECOND)).toHaveAttribute("data-priority", "critical");
  await expect(mark(page, SECOND)).toContainText(SECOND);
  await expect(page.getByTestId("robot-select").locator(`option[value="${SECOND}"]`)).toContainText("alarm: critical");
  // A line in the banner naming it, its most urgent alarm in words; this robot's own banner quiet.
  await expect(otherLine(page, SECOND)).toContainText(`${SECOND}: Emergency stop`);
  await expect(otherLine(page, SECOND)).toContainText("critical, active, unacknowledged");
  await expect(page.getByTestId("alarm-banner")).toHaveCount(0);
  await expect(mark(page, FIRST)).toHaveCount(0);
  await screenshot(page, testInfo, "other-robot-alarm");
  expect(await seriousViolations(page, "#panel-header"), "the header with another robot's alarm").toEqual([]);

  // The mark opens the second robot's panel, where the alarm is its own.
  await mark(page, SECOND).click();
  await expect(page).toHaveURL(new RegExp(`/\\?robot=${SECOND}$`));
  await expect(page.getByTestId("alarm-banner")).toHaveAttribute("data-alarm", `${SECOND}:emergency_stop`);
  await expect(page.getByTestId("robot-alarm-mark")).toHaveCount(0);
  await expect(page.getByTestId("alarm-banner-other")).toHaveCount(0);

  // Back on the first robot: once the second's alarm is reset and acknowledged, the mark goes.
  await page.goBack();
  await expect(page.getByTestId("robot-select")).toHaveValue(FIRST);
  await expect(mark(page, SECOND)).toBeVisible();
  await robot2.normalize();
  const ack = await operatorApi.api.post("/api/v1/alarms/ack", { data: { robot: SECOND } });
  expect(ack.status(), await ack.text()).toBe(200);
  await expect(page.getByTestId("robot-alarm-mark")).toHaveCount(0);
  await expect(page.getByTestId("alarm-banner-other")).toHaveCount(0);
});

test("acknowledge all shown: one request, one audited acknowledgement per alarm; a suppressed consequence shown as such", async ({
  page,
  robot,
  robot2,
  operatorApi,
}, testInfo) => {
  await quietCell([robot, robot2], operatorApi, "e2e 32: quiet start");
  const acks: string[] = [];
  page.on("request", (r) => {
    if (r.method() === "POST" && new URL(r.url()).pathname.startsWith("/api/v1/alarms/")) acks.push(new URL(r.url()).pathname);
  });
  await loggedIn(page, settings.operator);
  await page.goto(`/?robot=${FIRST}#alarms`);
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");

  // An e-stop: its reset brings SAFE_OFF, a consequence the service suppresses by design.
  await robot.estop();
  const estop = page.locator(`[data-testid="alarm-row"][data-alarm="${FIRST}:emergency_stop"]`);
  await expect(estop).toHaveAttribute("data-state", "active_unacknowledged");
  // Its reset passes through SAFE_OFF for half a second; held there (the emulator's forced
  // state) so that the list can be read while it lasts.
  await robot.setState(SAFE_OFF);
  const safeOff = page.locator(`[data-testid="alarm-row"][data-alarm="${FIRST}:safe_off"]`);
  await expect(safeOff).toHaveAttribute("data-state", "suppressed");
  await expect(safeOff.getByTestId("alarm-state")).toContainText("suppressed by design: a consequence of Emergency stop");
  await expect(safeOff.getByTestId("alarm-ack")).toHaveCount(0);
  await robot.normalize();
  // Back to normal: the e-stop returned, unacknowledged, its words naming the state.
  await expect(estop).toHaveAttribute("data-state", "returned_unacknowledged");
  // Then a protective stop and its reset: a second alarm waiting for a person.
  await robot.post("/protective-stop");
  const protective = page.locator(`[data-testid="alarm-row"][data-alarm="${FIRST}:protective_stop"]`);
  await expect(protective).toHaveAttribute("data-unacknowledged", "true");
  await robot.normalize();

  const all = page.getByTestId("alarm-ack-all");
  await expect(all).toBeEnabled();
  const count = Number(await all.getAttribute("data-count"));
  expect(count).toBeGreaterThanOrEqual(2);
  await expect(page.getByTestId("alarm-unack-mark")).toHaveCount(count);
  await screenshot(page, testInfo, "acknowledge-all");
  const before = await auditRows(operatorApi);
  const newestBefore = Math.max(0, ...before.map((r) => r.id));
  await all.click();
  await expect(page.getByTestId("alarm-ack-all-outcome")).toContainText(`${count} acknowledged`);
  await expect(page.getByTestId("alarm-unack-mark")).toHaveCount(0);
  await expect(all).toBeDisabled();
  await expect(page.getByTestId("alarm-banner")).toHaveCount(0);
  // One request for all of them.
  expect(acks).toEqual(["/api/v1/alarms/ack"]);

  // The audit trail: one acknowledgement per alarm, by the operator.
  const rows = (await auditRows(operatorApi)).filter((r) => r.id > newestBefore && r.action === "alarm.ack" && r.outcome === "acknowledged");
  expect(rows.map((r) => r.user)).toEqual(Array<string>(count).fill(settings.operator.name));
});
