// Scenario 3: every one of the 21 robot states, forced in turn, shows its name.
import { expect, test } from "../support/fixtures";

interface RobotStateInfo {
  value: number;
  name: string;
  description: string;
}

test("every robot state forced in turn shows its name", async ({ page, robot, request }) => {
  // The names come from the layout the service publishes, not from a copy here.
  const layout = (await (await request.get("/api/v1/layout")).json()) as { robot_states: RobotStateInfo[] };
  expect(layout.robot_states).toHaveLength(21);

  await page.goto("/");
  const badge = page.getByTestId("robot-state");
  await expect(badge).toHaveText("STANDALONE_RUNNING");
  for (const state of layout.robot_states) {
    await robot.setState(state.value);
    await expect(badge, `state ${state.value}`).toHaveText(state.name);
    await expect(badge).toHaveAttribute("data-state-value", String(state.value));
    await expect(badge).toHaveAttribute("title", state.description);
  }
});
