// Scenario 1: live data. The state badge shows STANDALONE_RUNNING, the joint plots grow, and
// the frame age is renewed as frames arrive.
import { expect, screenshot, test } from "../support/fixtures";

const JOINT_PLOTS = [
  "plot-joint-position",
  "plot-joint-velocity",
  "plot-joint-motor-current",
  "plot-joint-motor-temperature",
  "plot-joint-torque",
  "plot-joint-external-torque",
];

test("the panel shows the running robot live", async ({ page }, testInfo) => {
  await page.goto("/");
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  await expect(page.getByTestId("flag-servo-on")).toHaveAttribute("data-state", "on");
  await expect(page.getByTestId("flag-emergency-stopped")).toHaveAttribute("data-state", "off");

  // Every joint plot grows: more points, and its newest sample moves on in time.
  const plotState = () =>
    page.evaluate((ids) => {
      return ids.map((id) => {
        const el = document.querySelector(`[data-testid="${id}"]`) as (HTMLElement & { data?: { x?: unknown[] }[] }) | null;
        const xs = el?.data?.[0]?.x ?? [];
        // A plot nobody points at is a canvas picture (issue 24): its newest time is on the element.
        const last = el?.dataset.renderer === "canvas" ? (el.dataset.xTo ?? null) : xs.length > 0 ? xs[xs.length - 1] : null;
        return { id, points: Number(el?.dataset.points ?? "0"), last: last === null ? null : String(last) };
      });
    }, JOINT_PLOTS);
  await expect.poll(async () => (await plotState()).every((p) => p.points > 0), { message: "every joint plot has points" }).toBe(true);
  const before = await plotState();
  await expect
    .poll(
      async () => {
        const after = await plotState();
        return after.filter((p, i) => {
          const earlier = before[i]!;
          return p.last !== null && p.last !== earlier.last && p.points >= earlier.points;
        }).map((p) => p.id);
      },
      { message: "every joint plot appended newer samples" },
    )
    .toEqual(JOINT_PLOTS);

  // The frame age is renewed as frames arrive: it changes, and comes back under the 1 s after
  // which the display calls a frame stale. (How small it stays is a speed figure: bench/ui.)
  const frameAge = page.getByTestId("frame-age");
  const ages: number[] = [];
  await expect
    .poll(
      async () => {
        ages.push(Number(await frameAge.getAttribute("data-age-ms")));
        return new Set(ages).size >= 3 && ages.some((age) => age < 1000);
      },
      { message: "the frame age is renewed" },
    )
    .toBe(true);
  testInfo.annotations.push({ type: "frame ages (ms)", description: ages.join(", ") });
  await expect(frameAge).toHaveText(/^\d+(\.\d)? (ms|s)$/);
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "STANDALONE_RUNNING");

  await screenshot(page, testInfo, "panel");
});
