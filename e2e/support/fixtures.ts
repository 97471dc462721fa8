/**
 * Test fixtures: the emulator's control API (to cause things on the robot), the service's API
 * as a script would use it (to set up and to check what is not on screen), the emulator
 * process (to kill and restart it), and a reset of the robot before every test, because every
 * test shares the one emulator.
 */
import { expect, request as playwrightRequest, test as base, type APIRequestContext, type Page, type TestInfo } from "@playwright/test";
import { readFileSync } from "node:fs";
import { baseURL, control2URL, controlURL, emulatorPidFile, settings } from "./settings";

export interface EmulatorStatus {
  readonly frame: Record<string, unknown> & {
    robot_state: number;
    robot_state_name: string;
    controlbox_do: boolean[];
    analog_output: number[];
    analog_output_type: number[];
    bit_output_registers: boolean[];
  };
  readonly robot: { phase: string; program_running: boolean } & Record<string, unknown>;
  readonly plc_command: Record<string, unknown> & { controlbox_do: boolean[]; bit_input_registers: boolean[] };
  readonly faults: Record<string, unknown>;
  readonly connections: unknown[];
}

/** The emulator's control API (docs/emulator.md). */
export class Robot {
  constructor(private readonly api: APIRequestContext) {}

  async status(): Promise<EmulatorStatus> {
    const answer = await this.api.get("/status");
    expect(answer.status(), await answer.text()).toBe(200);
    return (await answer.json()) as EmulatorStatus;
  }

  /** POST and expect success; returns the JSON answer. */
  async post(path: string, body?: object): Promise<unknown> {
    // JSON always, an empty object for no fields: the control API takes JSON only.
    const answer = await this.api.post(path, { data: body ?? {} });
    expect(answer.status(), `POST ${path}: ${await answer.text()}`).toBe(200);
    return answer.json();
  }

  /** POST that may be refused (409: nothing to do in this state); returns the status. */
  async tryPost(path: string, body?: object): Promise<number> {
    // JSON always, an empty object for no fields: the control API takes JSON only.
    const answer = await this.api.post(path, { data: body ?? {} });
    return answer.status();
  }

  estop = () => this.post("/estop");
  reset = () => this.post("/reset");
  setState = (robot_state: number) => this.post("/state", { robot_state });
  setProgram = (running: boolean) => this.post("/program", { running });
  setFaults = (faults: object) => this.post("/faults", faults);
  clearFaults = () => this.post("/faults/clear");

  /** Back to a healthy robot running its demo program, whatever the last test left. */
  async normalize(): Promise<void> {
    await this.clearFaults();
    await this.post("/teach-button", { pressed: false });
    await this.post("/power-button", { pressed: false });
    await this.post("/collaborative", { enabled: false });
    let status = await this.status();
    if (status.robot.phase !== "normal" && status.robot.phase !== "initializing") {
      // 409: the robot refuses a reset in its phase now, e.g. one already under way (SAFE_OFF
      // for 0.5 s after the last test's reset); the poll below still demands the normal phase.
      expect([200, 409]).toContain(await this.tryPost("/reset"));
    }
    await expect
      .poll(async () => (status = await this.status()).robot.phase, { timeout: 10_000, message: "robot back in its normal phase" })
      .toBe("normal");
    await this.setProgram(true);
    await expect
      .poll(async () => (await this.status()).frame.robot_state_name, { timeout: 5_000 })
      .toBe("STANDALONE_RUNNING");
  }
}

/** One robot in `GET /api/v1/robots` (the fields the tests read). */
export interface RobotListed {
  readonly name: string;
  readonly connection: string;
  readonly holder: { user: string } | null;
  readonly robot_state_name: string | null;
  readonly model: string | null;
}

/** The service's API as a script uses it (bearer token), for setup and for checks. */
export class Service {
  constructor(readonly api: APIRequestContext) {}

  static async login(user: { name: string; password: string }): Promise<Service> {
    const anonymous = await playwrightRequest.newContext({ baseURL });
    const answer = await anonymous.post("/api/v1/auth/login", { data: { username: user.name, password: user.password } });
    expect(answer.status(), await answer.text()).toBe(200);
    const { token } = (await answer.json()) as { token: string };
    await anonymous.dispose();
    return new Service(await playwrightRequest.newContext({ baseURL, extraHTTPHeaders: { Authorization: `Bearer ${token}` } }));
  }

  async status(): Promise<{ connection: { state: string; gaps: number }; control: { holder: { user: string } | null } }> {
    const answer = await this.api.get("/api/v1/status");
    expect(answer.status()).toBe(200);
    return answer.json();
  }

  /** The service's robots as `GET /api/v1/robots` lists them. */
  async robots(): Promise<RobotListed[]> {
    const answer = await this.api.get("/api/v1/robots");
    expect(answer.status(), await answer.text()).toBe(200);
    return ((await answer.json()) as { robots: RobotListed[] }).robots;
  }

  /** Take control, PATCH, release: puts outputs back where a test expects them. */
  async write(patch: object): Promise<void> {
    const take = await this.api.post("/api/v1/control/take");
    expect(take.status(), `take control: ${await take.text()}`).toBe(200);
    try {
      const answer = await this.api.patch("/api/v1/command", { data: patch });
      expect(answer.status(), `PATCH ${JSON.stringify(patch)}: ${await answer.text()}`).toBe(200);
    } finally {
      await this.api.post("/api/v1/control/release");
    }
  }

  dispose = () => this.api.dispose();
}

/** The emulator process (under the supervisor started by the webServer). */
export const emulatorProcess = {
  pids(): { supervisor: number; emulator: number | null } {
    return JSON.parse(readFileSync(emulatorPidFile, "utf8")) as { supervisor: number; emulator: number | null };
  },
  kill(): number {
    const { emulator } = this.pids();
    if (emulator === null) throw new Error("the emulator is not running");
    process.kill(emulator, "SIGKILL");
    return emulator;
  },
  /** Start it again (no-op while it runs); resolves once the new process is recorded. */
  async restart(): Promise<number> {
    const { supervisor } = this.pids();
    process.kill(supervisor, "SIGUSR1");
    let pid: number | null = null;
    await expect.poll(() => (pid = this.pids().emulator), { timeout: 10_000, message: "emulator restarted" }).not.toBeNull();
    return pid as unknown as number;
  },
};

/** A screenshot kept with the test's results (attached to the report and as a file). */
export async function screenshot(page: Page, testInfo: TestInfo, name: string): Promise<void> {
  const file = testInfo.outputPath(`${name}.png`);
  await page.screenshot({ path: file, fullPage: false });
  await testInfo.attach(name, { path: file, contentType: "image/png" });
}

/** Log in through the panel's form as `user`. */
export async function loginInPanel(page: Page, user: { name: string; password: string }): Promise<void> {
  await page.getByTestId("login-username").fill(user.name);
  await page.getByTestId("login-password").fill(user.password);
  await page.getByTestId("login-submit").click();
  await expect(page.getByTestId("current-user")).toContainText(user.name);
}

interface Fixtures {
  robot: Robot;
  /** The second robot (the M0609); tests that use it put it back to running themselves. */
  robot2: Robot;
  operatorApi: Service;
}

export const test = base.extend<Fixtures & { healthyRobot: void }>({
  robot: async ({}, use) => {
    const api = await playwrightRequest.newContext({ baseURL: controlURL });
    await use(new Robot(api));
    await api.dispose();
  },
  robot2: async ({}, use) => {
    const api = await playwrightRequest.newContext({ baseURL: control2URL });
    await use(new Robot(api));
    await api.dispose();
  },
  operatorApi: async ({}, use) => {
    const service = await Service.login(settings.operator);
    await use(service);
    await service.dispose();
  },
  // Before every test: the emulator runs, the robot is healthy and moving, the service is
  // connected to it, and nobody holds control.
  healthyRobot: [
    async ({ robot }, use) => {
      if (emulatorProcess.pids().emulator === null) await emulatorProcess.restart();
      await expect.poll(async () => (await robot.tryPost("/faults/clear")), { timeout: 20_000, message: "emulator control API up" }).toBe(200);
      await robot.normalize();
      const anonymous = await playwrightRequest.newContext({ baseURL });
      await expect
        .poll(async () => (await anonymous.get("/readyz")).status(), { timeout: 20_000, message: "service connected to the robot" })
        .toBe(200);
      await anonymous.dispose();
      await use();
    },
    { auto: true },
  ],
});

export { expect };

/** Record every `data-state` an element goes through from now on (a brief "pending" too). */
export async function watchStates(page: Page, testId: string): Promise<void> {
  await page.getByTestId(testId).waitFor();
  await page.evaluate((id) => {
    const w = window as unknown as { __e2eStates?: Record<string, (string | null)[]> };
    const el = document.querySelector(`[data-testid="${id}"]`);
    if (el === null) throw new Error(`no element ${id}`);
    const seen: (string | null)[] = [el.getAttribute("data-state")];
    (w.__e2eStates ??= {})[id] = seen;
    new MutationObserver(() => {
      const state = el.getAttribute("data-state");
      if (seen[seen.length - 1] !== state) seen.push(state);
    }).observe(el, { attributes: true, attributeFilter: ["data-state"] });
  }, testId);
}

export async function seenStates(page: Page, testId: string): Promise<(string | null)[]> {
  return page.evaluate((id) => (window as unknown as { __e2eStates?: Record<string, (string | null)[]> }).__e2eStates?.[id] ?? [], testId);
}

/** Answer the confirmation dialog with yes, if the panel asks. */
export async function confirmIfAsked(page: Page): Promise<void> {
  const dialog = page.getByTestId("confirm-dialog");
  if (await dialog.isVisible()) await page.getByTestId("confirm-yes").click();
}

/** Open the panel, log in as the operator and take control. */
export async function operatorWithControl(page: Page): Promise<void> {
  await page.goto("/");
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  await loginInPanel(page, settings.operator);
  await page.getByTestId("take-control").click();
  await expect(page.getByTestId("control-holder")).toHaveAttribute("data-holder", settings.operator.name);
  await expect(page.getByTestId("control-holder")).toContainText(settings.operator.name);
  await expect(page.getByTestId("release-control")).toBeVisible();
}

/**
 * Note, in the page, the wall-clock time (ms since the epoch) at which `testId` first shows
 * `text` (or, with `attribute`, that attribute's value): when a person could first see it,
 * free of the test runner's polling delays. Read it with `seenAt`.
 */
export async function noteWhen(page: Page, name: string, testId: string, wanted: { text?: string; attribute?: [string, string] }): Promise<void> {
  await page.getByTestId(testId).waitFor();
  await page.evaluate(
    ({ name, testId, wanted }) => {
      const w = window as unknown as { __e2eTimes?: Record<string, number> };
      const times = (w.__e2eTimes ??= {});
      delete times[name];
      const el = document.querySelector(`[data-testid="${testId}"]`);
      if (el === null) throw new Error(`no element ${testId}`);
      const holds = () =>
        wanted.attribute !== undefined ? el.getAttribute(wanted.attribute[0]) === wanted.attribute[1] : el.textContent === wanted.text;
      const observer = new MutationObserver(() => {
        if (times[name] === undefined && holds()) {
          times[name] = Date.now();
          observer.disconnect();
        }
      });
      observer.observe(el, { attributes: true, childList: true, subtree: true, characterData: true });
    },
    { name, testId, wanted },
  );
}

export async function seenAt(page: Page, name: string): Promise<number | undefined> {
  return page.evaluate((name) => (window as unknown as { __e2eTimes?: Record<string, number> }).__e2eTimes?.[name], name);
}
