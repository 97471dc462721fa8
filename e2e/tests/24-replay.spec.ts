// Scenario 24 (issue 14, Replay): an incident re-run from its recording. The worker's robot runs
// its program and is e-stopped; the worker's service's recording of those seconds is exported
// (MCAP, as a person would from the panel or the API) and replayed by its own
// `cobot-hmi emulator --replay FILE --loop` on an address of its own, watched by its own
// `cobot-hmi serve` (support/replay.ts: the worker's cell and its two robots stay as they
// are). That panel shows the incident again: the state in the e-stop's plain words, the alarm
// banner, and the joint table holding the recorded values of the stopped arm.
import type { Page } from "@playwright/test";
import { writeFileSync } from "node:fs";
import { LAYOUT } from "../../frontend/src/generated/layout";
import { expect, recordedUntil, screenshot, Service, test } from "../support/fixtures";
import { type Child, replaySettings, startReplayCell } from "../support/replay";
import { settings } from "../support/settings";

const ESTOP = LAYOUT.robot_states.find((s) => s.name === "EMERGENCY_STOP")!;
const RUNNING = LAYOUT.robot_states.find((s) => s.name === "STANDALONE_RUNNING")!;
const RUNNING_S = 2;
const STOPPED_S = 3;

const children: Child[] = [];

test.afterAll(async () => {
  // Whatever happened: the spec's own emulator and service stop with it.
  await Promise.all(children.map((child) => child.stop()));
});

interface Row {
  readonly time_s: number;
  readonly robot_state: number;
  readonly joint_position: number[];
}

/** The recording of [from_s, to_s) as the CSV export has it (joint positions and the state). */
async function recordedRows(service: Service, from_s: number, to_s: number): Promise<Row[]> {
  const answer = await service.api.get(`/api/v1/robots/${settings.robotName}/export`, {
    params: { from: from_s, to: to_s, format: "csv", fields: "joint_position,robot_state" },
  });
  expect(answer.status(), await answer.text()).toBe(200);
  const [header, ...lines] = (await answer.text()).trim().split(/\r?\n/);
  const names = header!.split(",").map((name) => name.replaceAll('"', ""));
  const column = (name: string) => names.findIndex((n) => n === name || n.startsWith(`${name} [`));
  // Export columns carry the screen's labels (J 1 … J 6: joint_position.J1 …).
  const joints = [1, 2, 3, 4, 5, 6].map((j) => column(`joint_position.J${j}`));
  const state = column("robot_state");
  const time = column("time");
  expect(Math.min(state, time, ...joints), header).toBeGreaterThanOrEqual(0);
  return lines.map((line) => {
    const cells = line.split(",");
    return {
      time_s: Date.parse(cells[time]!.replaceAll('"', "")) / 1000,
      robot_state: Number(cells[state]),
      joint_position: joints.map((j) => Number(cells[j])),
    };
  });
}

/** The joint table's positions (their raw values), joint 1 to 6. */
async function shownPositions(page: Page): Promise<number[]> {
  return page.getByTestId("joint-table").evaluate((table) =>
    Array.from(table.querySelectorAll<HTMLElement>('td[data-field="joint_position"]'))
      .sort((a, b) => Number(a.closest("tr")?.dataset.joint) - Number(b.closest("tr")?.dataset.joint))
      .map((td) => Number(td.dataset.value)),
  );
}

test("a recorded e-stop replayed with --loop re-runs on its own HMI: the state's words, the alarm banner, the recorded joints", async ({
  page,
  robot,
}, testInfo) => {
  // A recording, an export, two processes started and a loop watched: generous on a busy machine.
  test.setTimeout(180_000);
  const viewer = await Service.login(settings.viewer);
  try {
    // The incident, recorded by the worker's service: the program running (since the test's
    // set-up) for RUNNING_S, then an e-stop for STOPPED_S.
    const from_s = Date.now() / 1000;
    await recordedUntil(viewer.api, from_s + RUNNING_S, "the program running recorded");
    await robot.estop();
    await expect.poll(async () => (await robot.status()).frame.robot_state_name).toBe("EMERGENCY_STOP");
    await recordedUntil(viewer.api, Date.now() / 1000 + STOPPED_S, "the stop recorded");
    const to_s = Date.now() / 1000;
    await robot.reset();

    // Once the recorder has flushed the range (it does at least every second): its rows.
    let rows: Row[] = [];
    await expect
      .poll(async () => (rows = await recordedRows(viewer, from_s, to_s)).at(-1)?.time_s ?? 0, { message: "the range recorded" })
      .toBeGreaterThan(to_s - 0.5);
    const states = rows.map((row) => row.robot_state);
    expect(states[0], "the recording starts with the program running").toBe(RUNNING.value);
    expect(states.at(-1), "and ends in the e-stop").toBe(ESTOP.value);
    // The stopped arm holds still: its joints are the last frame's from the first monitoring
    // refresh after the stop on (the emulator refreshes positions every 100 ms; a frame or
    // two of the stop may still carry the sample from just before it).
    const stopped = rows.filter((row) => row.robot_state === ESTOP.value);
    const held = stopped.at(-1)!.joint_position;
    for (const row of stopped.filter((r) => r.time_s > stopped[0]!.time_s + 0.5)) expect(row.joint_position).toEqual(held);
    const moving = rows.filter((row) => row.robot_state === RUNNING.value);
    expect(moving.some((row) => row.joint_position.some((v, i) => v !== held[i])), "the arm moved before").toBe(true);

    const mcap = await viewer.api.get(`/api/v1/robots/${settings.robotName}/export`, {
      params: { from: from_s, to: to_s, format: "mcap" },
    });
    expect(mcap.status(), await mcap.text()).toBe(200);
    const recording = testInfo.outputPath("incident.mcap");
    writeFileSync(recording, await mcap.body());

    // Its own emulator replays it in a loop; its own service watches that robot.
    const cell = await startReplayCell(recording, (child) => children.push(child));
    await page.goto(`${cell.baseURL}/?robot=${replaySettings.robotName}`);
    const badge = page.getByTestId("robot-state");
    await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");

    // The incident re-runs: the program running, then the stop in its plain words ...
    await expect(badge).toHaveAttribute("data-state-name", RUNNING.name, { timeout: 30_000 });
    await expect(badge).toHaveAttribute("data-state-name", ESTOP.name, { timeout: 30_000 });
    await expect(badge).toHaveText(ESTOP.label);
    // ... and the alarm banner, raised by the replayed stop.
    const banner = page.getByTestId("alarm-banner");
    await expect(banner).toHaveAttribute("data-alarm", `${replaySettings.robotName}:emergency_stop`);
    await screenshot(page, testInfo, "replayed-emergency-stop");

    // While stopped, the joint table shows the recording's joints (float32 on the wire and in
    // the recording: equal to their precision).
    await expect
      .poll(
        async () => {
          if ((await badge.getAttribute("data-state-name")) !== ESTOP.name) return "not stopped now";
          const shown = await shownPositions(page);
          const off = shown.map((v, i) => Math.abs(v - held[i]!)).filter((d) => !(d <= 1e-3 * Math.max(1, Math.abs(held[0]!))));
          return shown.length === 6 && off.length === 0 ? "equal" : `shown ${shown.join(", ")}, recorded ${held.join(", ")}`;
        },
        { timeout: 30_000, message: "the joint table equals the recorded stopped arm" },
      )
      .toBe("equal");
    // And the loop runs it again: running once more, then stopped again.
    await expect(badge).toHaveAttribute("data-state-name", RUNNING.name, { timeout: 30_000 });
    await expect(badge).toHaveAttribute("data-state-name", ESTOP.name, { timeout: 30_000 });
  } finally {
    await viewer.dispose();
    await Promise.all(children.map((child) => child.stop()));
  }
});
