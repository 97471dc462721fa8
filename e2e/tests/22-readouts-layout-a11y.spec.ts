// Issue 13, numbers and every screen: the joint table shows the frame's values; a 390 × 844
// phone has no horizontal scrolling, a compact sticky header (a fifth of the height at most,
// nothing scrolling inside it, the essentials shown, the rest behind its menu), dialogs on
// screen and 44 px touch targets (every link and button); at 1280 × 800, 1920 × 1080 and
// 1440 × 920, in short windows (1366 × 657, 1024 × 600), on a tablet (768 × 1024) and on a phone held sideways
// (844 × 390), the header with an alarm within a fifth of the height,
// the banner whole in it; the confirmation dialog keeps focus, Escape cancels and Enter confirms (with a
// warning during an emergency stop). (axe-core's audits of the panel, the login and the kiosk:
// 11-accessibility.spec.ts.)
import type { Locator, Page } from "@playwright/test";
import { expect, loginInPanel, operatorWithControl, quietCell, test } from "../support/fixtures";
import { settings } from "../support/settings";

const DO16_INDEX = 15; // DO 1–16 are indexes 0–15 of controlbox_do

type Readout = { field: string; index: number; text: string; value: number };

/** The joint table's cells: layout field, joint index, shown text and raw value. */
async function jointTable(page: Page): Promise<Readout[]> {
  return page.getByTestId("joint-table").evaluate((table) =>
    Array.from(table.querySelectorAll<HTMLElement>("td[data-field]")).map((td) => ({
      field: td.dataset.field ?? "",
      index: Number(td.closest("tr")?.dataset.joint),
      text: td.textContent ?? "",
      value: Number(td.dataset.value),
    })),
  );
}

test("the joint table equals the frame's values", async ({ page, robot, request }) => {
  // A robot at rest: its joints stay where they are between the page and the REST read.
  await robot.setProgram(false);
  await page.goto("/");
  const table = page.getByTestId("joint-table");
  await expect(table).toBeVisible();
  // Units in the header, from the layout.
  await expect(table.locator("thead")).toContainText("Position [degree]");
  await expect(table.locator("thead")).toContainText("Motor temperature [°C]");
  await expect(table.locator("thead")).toContainText("External torque [N·m]");
  await expect(table.locator("tbody tr")).toHaveCount(6);

  const frameOf = async () => {
    const answer = await request.get(`/api/v1/robots/${settings.robotName}/frame`);
    expect(answer.status()).toBe(200);
    return ((await answer.json()) as { frame: Record<string, (number | null)[]> }).frame;
  };
  // Position and velocity of a robot at rest are exact; currents, temperatures and torques
  // move a little between two frames, so they are compared with a tolerance (the refresh).
  await expect
    .poll(
      async () => {
        const frame = await frameOf();
        const cells = await jointTable(page);
        const wrong: string[] = [];
        for (const cell of cells) {
          const expected = frame[cell.field]?.[cell.index];
          if (typeof expected !== "number") {
            if (cell.text !== "—") wrong.push(`${cell.field}[${cell.index}] shows ${cell.text}, frame has none`);
            continue;
          }
          // At rest, positions and velocities hold still; currents, temperatures and torques
          // carry the emulator's noise from one frame to the next (about ±0.5 of their unit).
          const exact = cell.field === "joint_position" || cell.field === "joint_velocity";
          const tolerance = exact ? 0.01 : Math.max(1, 0.05 * Math.abs(expected));
          if (!(Math.abs(cell.value - expected) <= tolerance)) wrong.push(`${cell.field}[${cell.index}] ${cell.value} ≠ ${expected}`);
          // The text is the value, rounded.
          const shown = Number(cell.text.replace("\u2212", "-"));
          if (!(Math.abs(shown - cell.value) <= 0.051)) wrong.push(`${cell.field}[${cell.index}] text ${cell.text} ≠ ${cell.value}`);
        }
        return cells.length === 36 ? wrong : [`${cells.length} cells`];
      },
      { message: "joint table = frame" },
    )
    .toEqual([]);

  // It follows the stream without React: the table counts the frames it has shown.
  const first = Number(await table.getAttribute("data-frames"));
  await expect.poll(async () => Number(await table.getAttribute("data-frames"))).toBeGreaterThan(first);
  await expect(page.getByTestId("tcp-readout")).toContainText("Position [mm]");
});

// Values that change ten times a second must not move what is beside them: a value that gains a
// digit or a minus sign used to widen its table column or push the connection figures sideways
// (the browser's layout-shift entries name the moved nodes). Counted over readout updates, not time.
test("live readouts move nothing sideways", async ({ page, robot }) => {
  await robot.setProgram(true);
  await page.goto("/");
  const table = page.getByTestId("joint-table");
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  await expect(table.locator("td").first()).not.toHaveText("—");
  await page.evaluate(() => {
    const moved: string[] = [];
    (window as unknown as { __moved: string[] }).__moved = moved;
    new PerformanceObserver((list) => {
      for (const entry of list.getEntries() as (PerformanceEntry & { sources?: { node?: Node | null }[] })[]) {
        for (const source of entry.sources ?? []) {
          const node = source.node;
          const el = node instanceof Element ? node : (node?.parentElement ?? null);
          const inside = el?.closest(".readout, .health__figures");
          if (inside) moved.push(`${el?.tagName.toLowerCase()}.${el?.className} in ${inside.className}`);
        }
      }
    }).observe({ type: "layout-shift" });
  });
  const first = Number(await table.getAttribute("data-frames"));
  await expect.poll(async () => Number(await table.getAttribute("data-frames")), { timeout: 30_000 }).toBeGreaterThan(first + 40);
  expect(await page.evaluate(() => (window as unknown as { __moved: string[] }).__moved)).toEqual([]);
});

test("the phone layout has no overflow and a compact header", async ({ browser, robot, operatorApi }) => {
  // Both robots' alarms acknowledged: an earlier scenario's on the other robot would add its line
  // to the header (issue 24), which this count of rows does not expect.
  for (const name of [settings.robotName, settings.robot2Name]) {
    const ack = await operatorApi.api.post("/api/v1/alarms/ack", { data: { robot: name, comment: "e2e 22: quiet start" } });
    expect(ack.status(), await ack.text()).toBe(200);
  }
  const context = await browser.newContext({ viewport: { width: 390, height: 844 }, hasTouch: true, isMobile: true });
  const page = await context.newPage();
  try {
    const noOverflow = async (where: string) => {
      const { width, wide } = await page.evaluate(() => ({
        width: document.documentElement.scrollWidth,
        // The outermost elements that reach past the right edge, to name in a failure.
        wide: Array.from(document.querySelectorAll<HTMLElement>("body *"))
          .filter((el) => {
            if (el.getBoundingClientRect().right <= 391) return false;
            // Not one inside a container that scrolls it (a wide table in its scroll box).
            for (let up = el.parentElement; up !== null && up !== document.body; up = up.parentElement) {
              if (up.getBoundingClientRect().right > 391) return false;
              const overflow = getComputedStyle(up).overflowX;
              if (overflow === "auto" || overflow === "scroll" || overflow === "hidden") return false;
            }
            return true;
          })
          .slice(0, 8)
          .map((el) => `${el.tagName.toLowerCase()}.${el.className} ${Math.round(el.getBoundingClientRect().right)}`),
      }));
      expect(width, `${where}: ${wide.join("; ")}`).toBeLessThanOrEqual(390);
    };
    // The sticky header: at most a fifth of the height, nothing scrolling inside it, and each
    // essential item (by test id) shown whole within it.
    // Measured until the layout has settled (a busy machine renders the header's parts apart).
    const headerCompact = async (where: string, essentials: string[]) => {
      const problems = async (): Promise<string[]> => {
        const shown = await page.getByTestId("panel-header").evaluate((header, ids) => {
          const box = header.getBoundingClientRect();
          return {
            height: box.height,
            scrollHeight: header.scrollHeight,
            clientHeight: header.clientHeight,
            missing: ids.filter((id) => {
              const el = header.querySelector<HTMLElement>(`[data-testid="${id}"]`);
              if (el === null) return true;
              const r = el.getBoundingClientRect();
              const inside = r.top >= box.top - 0.5 && r.bottom <= box.bottom + 0.5 && r.left >= -0.5 && r.right <= 390.5;
              return !(r.width > 0 && r.height > 0 && inside && getComputedStyle(el).visibility !== "hidden");
            }),
          };
        }, essentials);
        const wrong: string[] = [];
        if (shown.height > 0.2 * 844 + 0.5) wrong.push(`${where}: sticky header ${shown.height} px high`);
        if (shown.scrollHeight > shown.clientHeight + 1) wrong.push(`${where}: the header scrolls inside itself`);
        if (shown.missing.length > 0) wrong.push(`${where}: essentials not shown in the header: ${shown.missing.join(", ")}`);
        return wrong;
      };
      await expect.poll(problems, { timeout: 15_000 }).toEqual([]);
    };
    const ESSENTIALS = ["robot-select", "robot-state", "connection-status", "control-holder", "header-menu"];
    const touchTargetsBigEnough = async () => {
      const small = await page.evaluate(() => {
        const out: string[] = [];
        for (const el of Array.from(document.querySelectorAll<HTMLElement>("a, button, select, input"))) {
          const target = el instanceof HTMLInputElement && (el.type === "checkbox" || el.type === "radio") ? (el.closest("label") ?? el) : el;
          const r = target.getBoundingClientRect();
          if (r.width === 0 || r.height === 0 || getComputedStyle(el).visibility === "hidden") continue; // not shown
          if (r.width < 44 || r.height < 44) out.push(`${el.dataset.testid ?? el.getAttribute("aria-label") ?? el.textContent?.trim() ?? el.tagName} ${Math.round(r.width)}×${Math.round(r.height)}`);
        }
        return out;
      });
      expect(small, "touch targets under 44 × 44 px").toEqual([]);
    };

    await page.goto("/");
    await expect(page.getByTestId("joint-table")).toBeVisible();
    await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
    await noOverflow("panel, logged out");
    await headerCompact("logged out", [...ESSENTIALS, "login-open"]);
    await touchTargetsBigEnough();

    // The rest is behind the menu: "Log in" opens it at the form; Escape closes it again.
    const menu = page.getByTestId("header-menu");
    await expect(page.getByTestId("login-username")).toBeHidden();
    await expect(page.getByTestId("flag-servo-on")).toBeHidden();
    await menu.click();
    await expect(menu).toHaveAttribute("aria-expanded", "true");
    await expect(page.getByTestId("flag-servo-on")).toBeVisible();
    await expect(page.getByTestId("frame-age")).toBeVisible();
    await noOverflow("panel, header menu open");
    await page.keyboard.press("Escape");
    await expect(menu).toHaveAttribute("aria-expanded", "false");
    await page.getByTestId("login-open").click();
    await expect(page.getByTestId("login-username")).toBeFocused();
    await loginInPanel(page, settings.operator);
    // Logged in: back to the essentials, with the session's action among them.
    await expect(menu).toHaveAttribute("aria-expanded", "false");
    await page.getByTestId("take-control").click();
    await expect(page.getByTestId("control-holder")).toHaveAttribute("data-holder", settings.operator.name);
    await noOverflow("panel, operator with control");
    await headerCompact("operator with control", [...ESSENTIALS, "release-control"]);
    await touchTargetsBigEnough();

    // A dialog is fully on screen.
    const toggle = page.getByTestId("do-16");
    await toggle.scrollIntoViewIfNeeded();
    await toggle.click();
    const dialog = page.getByTestId("confirm-dialog");
    await expect(dialog).toBeVisible();
    const box = await dialog.boundingBox();
    expect(box).not.toBeNull();
    if (box !== null) {
      expect(box.x).toBeGreaterThanOrEqual(0);
      expect(box.y).toBeGreaterThanOrEqual(0);
      expect(box.x + box.width).toBeLessThanOrEqual(390);
      expect(box.y + box.height).toBeLessThanOrEqual(844);
    }
    await page.getByTestId("confirm-no").click();
    await expect(dialog).toHaveCount(0);

    // An emergency stop: its alarm banner joins the essentials, the header stays compact.
    await robot.estop();
    await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "EMERGENCY_STOP");
    await expect(page.getByTestId("alarm-banner")).toBeVisible();
    await noOverflow("panel, alarm");
    await headerCompact("alarm", [...ESSENTIALS, "release-control", "alarm-banner"]);
    await touchTargetsBigEnough(); // the alarm banner's link to the alarm list among them

    await page.goto("/kiosk");
    await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", /.+/);
    await noOverflow("kiosk");
  } finally {
    await context.close();
  }
});

// Issue 13 on wider screens: with an emergency stop's alarm, the sticky header stays within a
// fifth of the height, nothing scrolls inside it, and the alarm banner is shown whole in it.
// Below 1440 × 920 (1280 × 800; a 1366 × 768 laptop's page is about 1366 × 657; a tablet; a phone
// held sideways) the header is the compact one, the login form behind "Log in" as on a phone; at
// most 500 px high it is one row, who holds control in its menu.
for (const { touch, ...viewport } of [
  { width: 1280, height: 800, touch: false },
  { width: 1920, height: 1080, touch: false },
  { width: 1440, height: 920, touch: false },
  { width: 1366, height: 657, touch: false },
  { width: 1024, height: 600, touch: false },
  { width: 768, height: 1024, touch: true },
  { width: 844, height: 390, touch: true },
]) {
  const compact = viewport.width < 1440 || viewport.height < 920;
  test(`the ${viewport.width} × ${viewport.height} header keeps the alarm in view`, async ({ browser, robot, robot2, operatorApi }) => {
    const context = await browser.newContext({ viewport, hasTouch: touch, isMobile: touch });
    const page = await context.newPage();
    try {
      // The other robot's alarm too: its line shares the banner's row, never adds one.
      await robot2.estop();
      await page.goto("/");
      await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
      if (compact) {
        await expect(page.getByTestId("login-username")).toBeHidden();
        await page.getByTestId("login-open").click();
      }
      await loginInPanel(page, settings.operator);
      await page.getByTestId("take-control").click();
      await expect(page.getByTestId("control-holder")).toHaveAttribute("data-holder", settings.operator.name);
      await robot.estop();
      await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "EMERGENCY_STOP");
      await expect(page.getByTestId("alarm-banner")).toBeVisible();
      // Measured until the layout has settled (the banner's line and the header's rows come with
      // separate renders on a busy machine); each rule that does not hold is named.
      const header = page.getByTestId("panel-header");
      const problems = async (): Promise<string[]> => {
        const shown = await header.evaluate((el) => {
          const box = el.getBoundingClientRect();
          const banner = el.querySelector<HTMLElement>('[data-testid="alarm-banner"]');
          const r = banner?.getBoundingClientRect();
          return {
            height: box.height,
            scrollHeight: el.scrollHeight,
            clientHeight: el.clientHeight,
            banner: r === undefined ? null : { top: r.top, bottom: r.bottom, left: r.left, right: r.right, width: r.width, height: r.height },
            box: { top: box.top, bottom: box.bottom },
            rows: Array.from(el.children).map((c) => `${c.className} ${Math.round(c.getBoundingClientRect().top)}+${Math.round(c.getBoundingClientRect().height)}`),
          };
        });
        const where = `${viewport.width} × ${viewport.height}: ${shown.rows.join("; ")}`;
        const wrong: string[] = [];
        if (shown.height > 0.2 * viewport.height + 0.5) wrong.push(`sticky header ${shown.height} px high`);
        if (shown.scrollHeight > shown.clientHeight + 1) wrong.push(`the header scrolls inside itself (${shown.scrollHeight} > ${shown.clientHeight})`);
        const b = shown.banner;
        if (b === null) wrong.push("no alarm banner in the header");
        else {
          if (!(b.width * b.height > 0)) wrong.push("the alarm banner has no area");
          if (b.top < shown.box.top - 0.5 || b.bottom > shown.box.bottom + 0.5) wrong.push(`the banner (${b.top}–${b.bottom}) leaves the header (${shown.box.top}–${shown.box.bottom})`);
          if (b.left < -0.5 || b.right > viewport.width + 0.5) wrong.push(`the banner (${b.left}–${b.right}) leaves the screen`);
        }
        return wrong.map((w) => `${w} — ${where}`);
      };
      await expect(page.getByTestId("alarm-banner-other")).toHaveAttribute("data-robot", settings.robot2Name);
      await expect.poll(problems, { timeout: 15_000 }).toEqual([]);
      await expect(page.getByTestId("alarm-banner")).toBeInViewport({ ratio: 1 });
      await expect(page.getByTestId("alarm-banner-other")).toBeInViewport({ ratio: 1 });
      const essentials = viewport.height > 500 ? ["robot-select", "robot-state", "connection-status", "control-holder"] : ["robot-state", "connection-status"];
      for (const id of [...essentials, "release-control", ...(compact ? ["header-menu"] : [])]) {
        await expect(header.getByTestId(id), `${viewport.width} × ${viewport.height}: ${id}`).toBeInViewport({ ratio: 1 });
      }
    } finally {
      await context.close();
      await quietCell([robot, robot2], operatorApi, "e2e 22: header layout");
    }
  });
}

/**
 * Press `key` on `control` with the keyboard and expect `opened` to show. The control must be
 * enabled and focused when the key goes down: on a loaded machine the panel can block writing
 * for a moment (its frames over a second old: "Cannot write while stale", the button disabled
 * with the reason as its title), and a key pressed then does nothing, as for a person. So what
 * the control was at the key's keydown is recorded in the page: a press on an enabled, focused
 * control that opens nothing fails at once; a press the panel blocked (its reason said) is made
 * again, a few times at most.
 */
async function pressToOpen(page: Page, control: Locator, key: string, opened: Locator): Promise<void> {
  const blocked: string[] = [];
  for (let attempt = 0; attempt < 3; attempt++) {
    await expect(control).toBeEnabled();
    await control.focus();
    await expect(control).toBeFocused();
    await control.evaluate((el) => {
      const w = window as unknown as { __e2eKeydown?: string };
      delete w.__e2eKeydown;
      document.addEventListener(
        "keydown",
        () => {
          const button = el as HTMLButtonElement;
          w.__e2eKeydown =
            document.activeElement !== el ? `focus on ${document.activeElement?.outerHTML.slice(0, 80) ?? "nothing"}` : button.disabled ? `disabled: ${button.title}` : "ok";
        },
        { capture: true, once: true },
      );
    });
    await page.keyboard.press(key);
    const atKeydown = await page.evaluate(() => (window as unknown as { __e2eKeydown?: string }).__e2eKeydown ?? "no keydown seen");
    if (atKeydown === "ok") {
      await expect(opened, `${key} on the enabled, focused control opens it`).toBeVisible();
      return;
    }
    blocked.push(atKeydown);
  }
  throw new Error(`the key never reached an enabled, focused control: ${blocked.join("; ")}`);
}

test("Escape closes the dialog, focus stays inside, Enter confirms", async ({ page, robot, operatorApi }) => {
  await operatorApi.write({ controlbox_do: { [DO16_INDEX]: false } }); // whatever a failed run left
  await operatorWithControl(page);
  const toggle = page.getByTestId("do-16");
  await toggle.scrollIntoViewIfNeeded();
  await expect(toggle).toHaveAttribute("data-state", "off");
  const dialog = page.getByTestId("confirm-dialog");

  // Keyboard only: the toggle is reachable and opens the question; the answer has the focus.
  await pressToOpen(page, toggle, "Space", dialog);
  await expect(page.getByTestId("confirm-yes")).toBeFocused();
  for (let i = 0; i < 3; i++) {
    await page.keyboard.press("Tab");
    expect(await dialog.evaluate((d) => d.contains(document.activeElement)), "focus stays in the dialog").toBe(true);
  }
  await page.keyboard.press("Shift+Tab");
  expect(await dialog.evaluate((d) => d.contains(document.activeElement))).toBe(true);
  await page.keyboard.press("Escape");
  await expect(dialog).toHaveCount(0);
  await expect(toggle).toBeFocused();
  expect((await robot.status()).frame.controlbox_do[DO16_INDEX]).toBe(false);

  // Enter confirms.
  await pressToOpen(page, toggle, "Space", dialog);
  await page.getByTestId("confirm-no").focus();
  await page.getByTestId("confirm-yes").focus();
  await page.keyboard.press("Enter");
  await expect(toggle).toHaveAttribute("data-state", "on");
  expect((await robot.status()).plc_command.controlbox_do[DO16_INDEX]).toBe(true);

  // During an emergency stop the question warns.
  await robot.estop();
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", "EMERGENCY_STOP");
  await toggle.click();
  await expect(page.getByTestId("confirm-warning")).toContainText("emergency stop");
  await page.getByTestId("confirm-yes").click();
  await expect(toggle).toHaveAttribute("data-state", "off");
});

test("the theme switch is remembered", async ({ page }) => {
  await page.emulateMedia({ colorScheme: "light" });
  await page.goto("/");
  await page.getByTestId("theme-switch").selectOption("dark");
  expect(await page.evaluate(() => document.documentElement.dataset.theme)).toBe("dark");
  await page.reload();
  await expect(page.getByTestId("theme-switch")).toHaveValue("dark");
  expect(await page.evaluate(() => document.documentElement.dataset.theme)).toBe("dark");
  await page.getByTestId("theme-switch").selectOption("system");
  expect(await page.evaluate(() => document.documentElement.dataset.theme)).toBe("light");
});
