// Scenario 34 (issue 23): an I/O checkout run by hand on the panel: the checker starts one, DI 5
// changes on the robot (its control API) and the row turns "seen" without anyone touching the
// screen; DO 3 is switched from the checkout (with control), the robot confirms it, the checker
// passes it with a comment, then switches it off: the evidence keeps both switches with their
// confirmation times (issue 38); a fail needs a comment; while the checkout is open no second one
// is offered, only to resume it; the printed page (print media) shows the report without a single
// button, with the signature lines. Then output presets: "All outputs off", which every robot
// has, and a preset saved from the registers being sent, each applied after a confirmation that
// lists what changes, and one typed by hand.
import type { Locator } from "@playwright/test";
import { expect, operatorWithControl, test } from "../support/fixtures";

const DI5 = "controlbox_di.4";
const DO3 = "controlbox_do.2";

test("a checkout run by hand: DI 5 seen, DO 3 passed, the printed report without buttons", async ({ page, robot, operatorApi }) => {
  await robot.post("/inputs", { controlbox_di: { "4": false } });
  await operatorApi.write({ controlbox_do: { "2": false } });
  await operatorWithControl(page);
  await page.locator("a[href='#checkout']").click();
  await page.getByTestId("checkout-start").click();
  await expect(page.getByTestId("checkout-header")).toContainText("I/O checkout");
  await expect(page.getByTestId("checkout-row")).toHaveCount(176);

  // An input: nobody touches the screen, the robot's frames mark it.
  await page.getByTestId("checkout-find").fill("DI 5");
  const di5 = page.locator(`[data-testid=checkout-row][data-key='${DI5}']`);
  await expect(di5).toHaveAttribute("data-result", "untested");
  await robot.post("/inputs", { controlbox_di: { "4": true } });
  await expect(di5).toHaveAttribute("data-result", "seen");
  await expect(di5.getByTestId("checkout-evidence")).toHaveText("off → on");

  // An output: switched from the checkout, confirmed by the robot, passed with a comment.
  await page.getByTestId("checkout-find").fill("DO 3");
  const do3 = page.locator(`[data-testid=checkout-row][data-key='${DO3}']`);
  await do3.getByTestId("checkout-switch-on").click();
  await expect(do3.getByTestId("checkout-evidence")).toHaveText(/^on confirmed \d\d:\d\d:\d\d$/);
  expect((await robot.status()).frame.controlbox_do[2]).toBe(true);
  await do3.getByTestId("checkout-comment").fill("valve opens");
  await do3.getByTestId("checkout-pass").click();
  await expect(do3).toHaveAttribute("data-result", "pass");
  await expect(do3).toContainText("valve opens");
  // Switched off again: what proved the pass stays in its evidence (issue 38).
  await do3.getByTestId("checkout-switch-off").click();
  await expect(do3.getByTestId("checkout-evidence")).toHaveText(/^on confirmed \d\d:\d\d:\d\d, off confirmed \d\d:\d\d:\d\d$/);
  await expect(do3).toHaveAttribute("data-result", "pass");

  // A fail needs a comment saying what is wrong.
  await page.getByTestId("checkout-find").fill("Tool DO 2");
  const toolDo2 = page.locator("[data-testid=checkout-row][data-key='tool_do.1']");
  await expect(toolDo2.getByTestId("checkout-fail")).toBeDisabled();
  await toolDo2.getByTestId("checkout-comment").fill("no wire at the tool flange");
  await toolDo2.getByTestId("checkout-fail").click();
  await expect(toolDo2).toHaveAttribute("data-result", "fail");

  // One open checkout per robot: no second one offered, the open one resumed.
  await expect(page.getByTestId("checkout-start")).toHaveCount(0);
  await page.getByTestId("checkout-choose").selectOption("");
  await page.getByTestId("checkout-resume").click();
  await expect(page.getByTestId("checkout-header")).toContainText("I/O checkout");
  await expect(page.getByTestId("checkout-resume")).toHaveCount(0);

  // The printed page: every point, the signature lines, no button anywhere.
  await page.getByTestId("checkout-find").fill("");
  await page.emulateMedia({ media: "print" });
  await expect(page.getByTestId("checkout-signatures")).toBeVisible();
  await expect(page.getByTestId("checkout-header")).toBeVisible();
  await expect(page.locator("button:visible")).toHaveCount(0);
  await expect(page.locator("input:visible")).toHaveCount(0);
  await expect(page.locator("[data-testid=checkout-row]:visible")).toHaveCount(176);
  await expect(di5).toContainText("seen");
  await expect(do3).toContainText("pass");
  await expect(do3.getByTestId("checkout-evidence")).toContainText("on confirmed");
  await expect(do3.getByTestId("checkout-evidence")).toContainText("off confirmed");
  await page.emulateMedia({ media: "screen" });
  await expect(page.getByTestId("checkout-signatures")).toBeHidden();

  // Closed: read-only.
  await page.getByTestId("checkout-close").click();
  await page.getByTestId("confirm-yes").click();
  await expect(page.getByTestId("checkout-header")).toContainText("closed");
  await expect(page.getByTestId("checkout-pass")).toHaveCount(0);
  await expect(page.getByTestId("checkout-start")).toBeVisible();
  await robot.post("/inputs", { controlbox_di: { "4": false } });
  await page.getByTestId("release-control").click();
});

/**
 * Press a button of the presets' section, at the page's end: the events and audit lists above it
 * grow as control is taken, and a click by position landed where the button had been a moment
 * before (a fresh clone: the save never asked, its name still filled, no note). The button's own
 * click, once it is enabled, is what a person's click on it does.
 */
async function pressInPlace(button: Locator): Promise<void> {
  await expect(button).toBeEnabled();
  await button.dispatchEvent("click");
}

test("output presets: All outputs off and a saved one, each applied after its confirmation", async ({ page, robot, operatorApi }) => {
  await operatorApi.write({ controlbox_do: { "3": true }, bit_input_registers: { "0": true, "1": true, "2": false, "3": false } });
  await operatorWithControl(page);
  await page.locator("a[href='#presets']").click();
  const presets = page.getByTestId("presets-view");

  // A preset from the registers being sent.
  await presets.getByTestId("preset-name").fill("Job 3");
  await pressInPlace(presets.getByTestId("preset-save"));
  await expect(presets.getByTestId("preset-note")).toContainText("saved");
  await expect(presets.locator("[data-testid=preset-row][data-name='Job 3']")).toBeVisible();

  // All outputs off: the confirmation lists DO 4, the robot reports it off.
  await presets.locator("[data-testid=preset-row][data-name='All outputs off']").getByTestId("preset-apply").click();
  await expect(page.getByTestId("confirm-dialog")).toContainText("DO 4: on → off");
  await page.getByTestId("confirm-yes").click();
  await expect(presets.getByTestId("preset-note")).toContainText("applied");
  await expect.poll(async () => (await robot.status()).frame.controlbox_do[3]).toBe(false);

  // Job 3 after the registers changed: both set again in one write.
  await page.getByTestId("release-control").click();
  await operatorApi.write({ bit_input_registers: { "0": false, "1": false } });
  await page.getByTestId("take-control").click();
  await presets.locator("[data-testid=preset-row][data-name='Job 3']").getByTestId("preset-apply").click();
  await expect(page.getByTestId("confirm-dialog")).toContainText("Register in 0: off → on; Register in 1: off → on");
  await page.getByTestId("confirm-yes").click();
  await expect(presets.getByTestId("preset-note")).toContainText("2 value(s) changed");
  const sent = (await robot.status()).plc_command.bit_input_registers;
  expect(sent.slice(0, 4)).toEqual([true, true, false, false]);

  // A preset typed by hand.
  await presets.getByTestId("preset-name").fill("Job 5");
  await presets.getByTestId("preset-values").fill("Register in 4 = on, Register in 5 = on");
  await pressInPlace(presets.getByTestId("preset-save-values"));
  await expect(presets.getByTestId("preset-note")).toContainText("saved");
  await presets.locator("[data-testid=preset-row][data-name='Job 5']").getByTestId("preset-apply").click();
  await page.getByTestId("confirm-yes").click();
  await expect(presets.getByTestId("preset-note")).toContainText("applied");
  expect((await robot.status()).plc_command.bit_input_registers.slice(4, 6)).toEqual([true, true]);
  await page.getByTestId("release-control").click();
});
