// Scenario 3: every one of the 21 robot states, forced in turn, shows its name in plain words,
// with the enum name in the tooltip and in data-state-name.
import { expect, test } from "../support/fixtures";

interface RobotStateInfo {
  value: number;
  name: string;
  label: string;
  description: string;
}

test("every robot state forced in turn shows its name", async ({ page, robot, request }) => {
  // The names come from the layout the service publishes, not from a copy here.
  const layout = (await (await request.get("/api/v1/layout")).json()) as { robot_states: RobotStateInfo[] };
  expect(layout.robot_states).toHaveLength(21);

  await page.goto("/");
  const badge = page.getByTestId("robot-state");
  await expect(badge).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");
  for (const state of layout.robot_states) {
    await robot.setState(state.value);
    await expect(badge, `state ${state.value}`).toHaveAttribute("data-state-name", state.name);
    await expect(badge).toHaveAttribute("data-state-value", String(state.value));
    await expect(badge).toHaveText(state.label);
    await expect(badge).toHaveAttribute("title", `${state.description} (${state.name})`);
  }
});
