// Scenario 21: control belongs to a session, not to a user name. The same operator logged in in
// two browsers: the one that took control shows Release and live toggles; the other says
// "held by you in another window", has no Release and no Take control, and its toggles stay
// disabled — whether it learns of the control live (an event) or from its hello (a reload).
import type { Browser } from "@playwright/test";
import { expect, operatorPanel, test } from "../support/fixtures";
import { baseURL, settings } from "../support/settings";

/** The operator logged in in two windows: two contexts, two cookie jars, two login sessions. */
async function operatorInTwoWindows(browser: Browser) {
  const first = await browser.newContext({ baseURL, viewport: { width: 1600, height: 1000 } });
  const second = await browser.newContext({ baseURL, viewport: { width: 1600, height: 1000 } });
  const a = await first.newPage();
  const b = await second.newPage();
  // Each window's own login session (the form's request from each context; the form itself is
  // 04's, 10's and 22's subject).
  await Promise.all([a, b].map((page) => operatorPanel(page)));
  return { a, b, close: async () => Promise.all([first.close(), second.close()]) };
}

test("the same user in a second window sees control held by you in another window", async ({ browser }) => {
  // Two live panels at once: generous on a busy machine.
  test.setTimeout(240_000);
  const { a, b, close } = await operatorInTwoWindows(browser);
  try {

    await a.getByTestId("take-control").click();
    await expect(a.getByTestId("control-holder")).toHaveAttribute("data-ownership", "you");
    await expect(a.getByTestId("release-control")).toBeVisible();
    await expect(a.getByTestId("do-3")).toBeEnabled();

    // The second window learns it from the control event.
    const holder = b.getByTestId("control-holder");
    await expect(holder).toHaveAttribute("data-holder", settings.operator.name);
    await expect(holder).toHaveAttribute("data-ownership", "you-elsewhere");
    await expect(holder).toContainText("held by you in another window");
    await expect(b.getByTestId("release-control")).toHaveCount(0);
    await expect(b.getByTestId("take-control")).toHaveCount(0);
    await expect(b.getByTestId("do-3")).toBeDisabled();
    await expect(b.getByTestId("write-blocked-reason")).toContainText("another window");

    // And from its hello after a reload (the login stays).
    await b.reload();
    await expect(b.getByTestId("current-user")).toContainText(settings.operator.name);
    await expect(b.getByTestId("control-holder")).toHaveAttribute("data-ownership", "you-elsewhere");
    await expect(b.getByTestId("release-control")).toHaveCount(0);
    await expect(b.getByTestId("do-3")).toBeDisabled();
    // The first window still holds it.
    await expect(a.getByTestId("release-control")).toBeVisible();

    await a.getByTestId("release-control").click();
    await expect(b.getByTestId("control-holder")).toHaveAttribute("data-holder", "");
    await expect(b.getByTestId("take-control")).toBeVisible();
  } finally {
    await close();
  }
});

// Logging out ends this window's session, so the service closes its stream (1008, "session
// ended"). The window itself asked for it: it reconnects at once without showing that notice,
// and the same user's other window keeps its own session and stream.
test("a window's own logout reconnects quietly; the other window stays logged in", async ({ browser }) => {
  test.setTimeout(240_000); // two live panels at once
  const { a, b, close } = await operatorInTwoWindows(browser);
  try {
    // Every reason the badge gives from now on (its title), however briefly shown.
    await a.getByTestId("connection-status").evaluate((badge) => {
      const seen: string[] = [];
      (window as unknown as { __reasons: string[] }).__reasons = seen;
      new MutationObserver(() => seen.push(badge.getAttribute("title") ?? "")).observe(badge, { attributes: true });
    });

    await a.getByTestId("logout").click();
    await expect(a.getByTestId("login-username")).toBeVisible();
    await expect(a.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
    const reasons = await a.evaluate(() => (window as unknown as { __reasons: string[] }).__reasons);
    expect(reasons.filter((r) => /session|closed the stream/i.test(r))).toEqual([]);

    await expect(b.getByTestId("current-user")).toContainText(settings.operator.name);
    await expect(b.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  } finally {
    await close();
  }
});
