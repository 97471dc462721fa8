// Scenario 4: an operator logs in, takes control and switches DO 3 on: the toggle shows
// pending, then on, and the emulator's status confirms the output is on; off likewise.
import { expect, loginInPanel, seenStates, takeControl, test, watchStates } from "../support/fixtures";
import { settings } from "../support/settings";

const DO3_INDEX = 2; // DO 1–16 are indexes 0–15 of controlbox_do

test("an operator switches DO 3 on and off", async ({ page, robot, operatorApi }) => {
  await operatorApi.write({ controlbox_do: { [DO3_INDEX]: false } }); // whatever a failed run left
  await page.goto("/");
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  await loginInPanel(page, settings.operator);
  await takeControl(page);
  const toggle = page.getByTestId("do-3");
  await expect(toggle).toHaveAttribute("data-state", "off");
  await expect(toggle).toBeEnabled();

  for (const [wanted, label] of [[true, "on"], [false, "off"]] as const) {
    await watchStates(page, "do-3");
    await toggle.click();
    // Outputs ask for confirmation first.
    await expect(page.getByTestId("confirm-dialog")).toContainText(`DO 3`);
    await expect(page.getByTestId("confirm-dialog")).toContainText(wanted ? "ON" : "OFF");
    await page.getByTestId("confirm-yes").click();
    await expect(toggle).toHaveAttribute("data-state", label);
    await expect(toggle).toHaveAttribute("data-command", label);
    await expect(toggle).toContainText(label.toUpperCase());
    // What a person saw: pending first, then the robot's actual state.
    expect(await seenStates(page, "do-3")).toEqual([wanted ? "off" : "on", "pending", label]);
    await expect(page.getByTestId("do-3-reason")).toHaveCount(0);
    // The robot itself reports it, and the PLC image it consumed says the same.
    const status = await robot.status();
    expect(status.frame.controlbox_do[DO3_INDEX]).toBe(wanted);
    expect(status.plc_command.controlbox_do[DO3_INDEX]).toBe(wanted);
  }

  await page.getByTestId("release-control").click();
  await expect(page.getByTestId("control-holder")).toHaveAttribute("data-holder", "");
});
