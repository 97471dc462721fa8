// Scenario 5: bit input register 40 on lights bit output register 40 (the emulator's robot
// program copies input register n to output register n).
import { confirmIfAsked, expect, operatorWithControl, test } from "../support/fixtures";

test("bit input register 40 on lights bit output register 40", async ({ page, robot, operatorApi }) => {
  await operatorApi.write({ bit_input_registers: { 40: false } });
  await operatorWithControl(page);
  const input = page.getByTestId("bit-in-40");
  const output = page.getByTestId("bit-out-40");
  await input.scrollIntoViewIfNeeded();
  await expect(input).toHaveAttribute("data-state", "off");
  await expect(output).toHaveAttribute("data-state", "off");

  await input.click();
  await confirmIfAsked(page);
  await expect(input).toHaveAttribute("data-state", "on");
  await expect(output).toHaveAttribute("data-state", "on");
  let status = await robot.status();
  expect(status.plc_command.bit_input_registers[40]).toBe(true);
  expect(status.frame.bit_output_registers[40]).toBe(true);
  // Only register 40 moved.
  await expect(page.getByTestId("bit-out-39")).toHaveAttribute("data-state", "off");
  await expect(page.getByTestId("bit-out-41")).toHaveAttribute("data-state", "off");

  await input.click();
  await confirmIfAsked(page);
  await expect(input).toHaveAttribute("data-state", "off");
  await expect(output).toHaveAttribute("data-state", "off");
  status = await robot.status();
  expect(status.frame.bit_output_registers[40]).toBe(false);
});
