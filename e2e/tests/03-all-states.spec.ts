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
  // What the badge shows, read in one go (a busy page answers each question slowly).
  const shown = () =>
    badge.evaluate((el) => ({
      name: el.getAttribute("data-state-name"),
      value: el.getAttribute("data-state-value"),
      text: el.textContent,
      title: el.getAttribute("title"),
    }));
  for (const state of layout.robot_states) {
    await robot.setState(state.value);
    await expect
      .poll(shown, { message: `state ${state.value}` })
      .toEqual({ name: state.name, value: String(state.value), text: state.label, title: `${state.description} (${state.name})` });
  }
});
