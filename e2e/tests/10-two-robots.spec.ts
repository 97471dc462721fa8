// Scenario 10: one service, two robots (an M1013 and an M0609). The fleet overview shows a tile
// per robot with that robot's own state, link and control holder; the panel switches robot (its
// stream, its state and its URL follow, and the back button returns); the kiosk shows the robot
// its URL names. The second robot is stopped (its program off) so the two states differ.
import type { Page } from "@playwright/test";
import { expect, loginInPanel, screenshot, test, type Robot } from "../support/fixtures";
import { settings } from "../support/settings";

const FIRST = settings.robotName;
const SECOND = settings.robot2Name;

/** Stop the second robot's program; resolves to the state it then reports (not RUNNING). */
async function stopSecond(robot2: Robot): Promise<string> {
  await robot2.normalize();
  await robot2.setProgram(false);
  let state = "";
  await expect
    .poll(async () => (state = (await robot2.status()).frame.robot_state_name), { message: "second robot stopped" })
    .not.toBe("STANDALONE_RUNNING");
  return state;
}

/** The paths of every WebSocket the page opens from now on. */
function watchSockets(page: Page): string[] {
  const paths: string[] = [];
  page.on("websocket", (ws) => paths.push(new URL(ws.url()).pathname));
  return paths;
}

const tile = (page: Page, name: string) => page.locator(`[data-testid="fleet-tile"][data-robot="${name}"]`);

test.afterEach(async ({ robot2, operatorApi }) => {
  await robot2.normalize();
  // The second robot's e-stop acknowledged: another robot's alarm shows in every panel (issue 24).
  const ack = await operatorApi.api.post("/api/v1/alarms/ack", { data: { robot: SECOND, comment: "e2e 10: quiet" } });
  expect(ack.status(), await ack.text()).toBe(200);
});

test("the fleet overview shows each robot with its own state, link and control", async ({ page, robot2, operatorApi }, testInfo) => {
  const secondState = await stopSecond(robot2);
  await page.goto("/fleet");
  const tiles = page.getByTestId("fleet-tile");
  await expect(tiles).toHaveCount(2);
  // In the service's order: the default robot first.
  await expect(tiles.nth(0)).toHaveAttribute("data-robot", FIRST);
  await expect(tiles.nth(1)).toHaveAttribute("data-robot", SECOND);
  await expect(tile(page, FIRST).getByTestId("robot-state")).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");
  await expect(tile(page, SECOND).getByTestId("robot-state")).toHaveAttribute("data-state-name", secondState);
  for (const name of [FIRST, SECOND]) {
    await expect(tile(page, name).getByTestId("fleet-connection")).toHaveAttribute("data-state", "connected");
    await expect(tile(page, name).getByTestId("fleet-holder")).toHaveAttribute("data-holder", "");
  }

  // Control of the second robot shows on its tile alone.
  const take = await operatorApi.api.post(`/api/v1/robots/${SECOND}/control/take`);
  expect(take.status(), await take.text()).toBe(200);
  try {
    await expect(tile(page, SECOND).getByTestId("fleet-holder")).toHaveAttribute("data-holder", settings.operator.name);
    await expect(tile(page, FIRST).getByTestId("fleet-holder")).toHaveAttribute("data-holder", "");
    await screenshot(page, testInfo, "fleet");
  } finally {
    await operatorApi.api.post(`/api/v1/robots/${SECOND}/control/release`);
  }
  await expect(tile(page, SECOND).getByTestId("fleet-holder")).toHaveAttribute("data-holder", "");

  // A tile opens that robot's panel.
  await tile(page, SECOND).getByTestId("fleet-panel-link").click();
  await expect(page).toHaveURL(new RegExp(`/\\?robot=${SECOND}$`));
  await expect(page.getByTestId("robot-select")).toHaveValue(SECOND);
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", secondState);
});

test("the panel switches robot: stream, state, control and URL follow", async ({ page, robot2, operatorApi }, testInfo) => {
  const secondState = await stopSecond(robot2);
  const sockets = watchSockets(page);
  const select = page.getByTestId("robot-select");
  const badge = page.getByTestId("robot-state");
  const status = page.getByTestId("connection-status");

  await page.goto("/");
  // Without ?robot= the panel shows the service's default (first) robot and names it in the URL.
  await expect(select).toHaveValue(FIRST);
  await expect(page).toHaveURL(new RegExp(`/\\?robot=${FIRST}$`));
  await expect(badge).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");
  await expect(status).toHaveAttribute("data-state", "connected");

  await select.selectOption(SECOND);
  await expect(page).toHaveURL(new RegExp(`/\\?robot=${SECOND}$`));
  await expect(badge).toHaveAttribute("data-state-name", secondState);
  await expect(status).toHaveAttribute("data-state", "connected");
  expect(sockets).toContain(`/api/v1/robots/${FIRST}/stream`);
  expect(sockets).toContain(`/api/v1/robots/${SECOND}/stream`);

  // Control is per robot: taking it here takes the second robot's, not the first's.
  await loginInPanel(page, settings.operator);
  await page.getByTestId("take-control").click();
  await expect(page.getByTestId("control-holder")).toHaveAttribute("data-holder", settings.operator.name);
  const holders = Object.fromEntries((await operatorApi.robots()).map((r) => [r.name, r.holder?.user ?? null]));
  expect(holders).toEqual({ [FIRST]: null, [SECOND]: settings.operator.name });
  await page.getByTestId("release-control").click();
  await expect(page.getByTestId("control-holder")).toHaveAttribute("data-holder", "");

  // What the second robot does is what the panel shows now.
  await robot2.estop();
  await expect(badge).toHaveAttribute("data-state-name", "EMERGENCY_STOP");
  await screenshot(page, testInfo, "panel-second-robot");

  // Back: the first robot again, live, untouched by the second's emergency stop.
  await page.goBack();
  await expect(select).toHaveValue(FIRST);
  await expect(badge).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");
  await expect(status).toHaveAttribute("data-state", "connected");
});

test("the kiosk shows the robot its URL names", async ({ page, robot2 }) => {
  const secondState = await stopSecond(robot2);
  const sockets = watchSockets(page);
  const requests: string[] = [];
  page.on("request", (r) => requests.push(`${r.method()} ${new URL(r.url()).pathname}`));

  await page.goto(`/kiosk?robot=${SECOND}`);
  await expect(page.getByTestId("kiosk-robot")).toHaveText(SECOND);
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", secondState);
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");

  await page.goto(`/kiosk?robot=${FIRST}`);
  await expect(page.getByTestId("kiosk-robot")).toHaveText(FIRST);
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");

  // Each page streamed its robot (a busy machine may make a kiosk reconnect: same path again).
  expect([...new Set(sockets)]).toEqual([`/api/v1/robots/${SECOND}/stream`, `/api/v1/robots/${FIRST}/stream`]);
  // Still read-only: nothing but GETs.
  expect(requests.filter((r) => !r.startsWith("GET "))).toEqual([]);
});
