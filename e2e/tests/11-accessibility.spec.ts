// Issue 13, accessibility: axe-core finds nothing serious on the login and the panel, on the
// panel of an operator holding control, and on the kiosk, light and dark. (The 3D view's own
// audit is scenario 14's.) Audits of pages that redraw plots all the time are the suite's
// longest tests: numbered to start early, so that the shorter ones fill the workers around them.
import { seriousViolations } from "../support/a11y";
import { expect, operatorWithControl, test } from "../support/fixtures";

for (const colorScheme of ["light", "dark"] as const) {
  test(`axe-core clean: login, panel and kiosk (${colorScheme})`, async ({ page }) => {
    // An audit of a page that redraws plots and numbers all the time is slow on a busy machine.
    test.setTimeout(300_000);
    await page.emulateMedia({ colorScheme });
    await page.goto("/");
    await expect(page.getByTestId("login-username")).toBeVisible();
    await expect(page.getByTestId("joint-table")).toHaveAttribute("data-frames", /[1-9]/);
    expect(await page.evaluate(() => document.documentElement.dataset.theme)).toBe(colorScheme);
    expect(await seriousViolations(page), "login and panel").toEqual([]);

    await operatorWithControl(page);
    expect(await seriousViolations(page), "panel with control").toEqual([]);

    await page.goto("/kiosk");
    await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", /.+/);
    expect(await seriousViolations(page), "kiosk").toEqual([]);
  });
}
