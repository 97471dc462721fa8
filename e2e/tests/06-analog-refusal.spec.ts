// Scenario 6: an out-of-range analog setpoint is refused by the panel before any confirmation
// is asked (the layout's range), the refusal goes once a valid value (decimal comma) is typed,
// Escape cancels the confirmation, and nothing changes on the robot.
import { expect, operatorWithControl, test } from "../support/fixtures";

test("an out-of-range analog setpoint is refused and the robot does not change", async ({ page, robot }) => {
  await operatorWithControl(page);
  const before = await robot.status();
  const ao = page.getByTestId("ao-0");
  await ao.scrollIntoViewIfNeeded();
  await expect(ao).toHaveAttribute("data-state", "idle");

  // Current output: 4–20 mA. 25 mA is out of range.
  await page.getByTestId("ao-0-type").selectOption("0");
  await page.getByTestId("ao-0-setpoint").fill("25");
  await page.getByTestId("ao-0-set").click();
  const dialog = page.getByTestId("confirm-dialog");
  await expect(dialog).toHaveCount(0);

  const reason = page.getByTestId("ao-0-reason");
  await expect(reason).toBeVisible();
  await expect(reason).toContainText("refused");
  await expect(reason).toContainText(/range|4|20/);
  await expect(ao).toHaveAttribute("data-state", "idle");

  // A valid value with a decimal comma: the refusal goes while typing; the question names it.
  await page.getByTestId("ao-0-setpoint").fill("12,5");
  await expect(reason).toHaveCount(0);
  await page.getByTestId("ao-0-set").click();
  await expect(dialog).toBeVisible();
  await expect(dialog).toContainText("12.5");
  // Escape cancels: no write.
  await page.keyboard.press("Escape");
  await expect(dialog).toHaveCount(0);
  await expect(page.getByTestId("ao-0-set")).toBeFocused();
  // The display stays truthful: it still shows what the robot reports.
  const after = await robot.status();
  await expect(ao).toHaveAttribute("data-value", String(after.frame.analog_output[0]));
  expect(after.frame.analog_output).toEqual(before.frame.analog_output);
  expect(after.frame.analog_output_type).toEqual(before.frame.analog_output_type);
  expect(after.plc_command.analog_output).toEqual(before.plc_command.analog_output);
  expect(after.plc_command.analog_output_type).toEqual(before.plc_command.analog_output_type);
});
