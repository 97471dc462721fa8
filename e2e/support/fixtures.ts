/**
 * Test fixtures: the worker's cell (support/cell.ts: its emulators, which a test may kill and
 * restart, and its service), the emulators' control API (to cause things on the robot), the
 * service's API as a script would use it (to set up and to check what is not on screen), and a
 * reset of the robot before every test, because the tests of a worker share its cell.
 */
import { expect, request as playwrightRequest, test as base, type APIRequestContext, type Page, type TestInfo } from "@playwright/test";
import { Cell } from "./cell";
import { baseURL, control2URL, controlURL, settings } from "./settings";

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
      .poll(async () => (status = await this.status()).robot.phase, { message: "robot back in its normal phase" })
      .toBe("normal");
    await this.setProgram(true);
    await expect
      .poll(async () => (await this.status()).frame.robot_state_name)
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

/**
 * For the helpers' API contexts (the service's, the emulators' control APIs): a connection per
 * request. A test holds these contexts through long idle stretches, and a kept-alive connection
 * the server closed for idleness raced a request written at that moment (ECONNRESET on a POST,
 * which a client must not resend: e2e 10's acknowledgement, e2e 22's /faults/clear).
 */
const ONE_CONNECTION_PER_REQUEST = { Connection: "close" } as const;

/** The service's API as a script uses it (bearer token), for setup and for checks. */
export class Service {
  constructor(readonly api: APIRequestContext) {}

  static async login(user: { name: string; password: string }): Promise<Service> {
    const anonymous = await playwrightRequest.newContext({ baseURL });
    const answer = await anonymous.post("/api/v1/auth/login", { data: { username: user.name, password: user.password } });
    expect(answer.status(), await answer.text()).toBe(200);
    const { token } = (await answer.json()) as { token: string };
    await anonymous.dispose();
    return new Service(
      await playwrightRequest.newContext({ baseURL, extraHTTPHeaders: { Authorization: `Bearer ${token}`, ...ONE_CONNECTION_PER_REQUEST } }),
    );
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

interface WorkerFixtures {
  /** The worker's emulators and service, started once per worker. */
  cell: Cell;
}

export const test = base.extend<Fixtures & { healthyRobot: void }, WorkerFixtures>({
  cell: [
    async ({}, use) => {
      const cell = new Cell();
      try {
        try {
          await cell.start();
        } catch (error) {
          throw new Error(`the worker's cell did not start: ${String(error)}\n${cell.output}`);
        }
        await use(cell);
      } finally {
        await cell.stop();
      }
    },
    // Two emulators and a service started on a busy machine: generous.
    { scope: "worker", auto: true, timeout: 180_000 },
  ],
  // The worker's own service (what the config's `use.baseURL` names too, in the worker).
  baseURL: async ({ cell }, use) => use(cell.baseURL),
  robot: async ({}, use) => {
    const api = await playwrightRequest.newContext({ baseURL: controlURL, extraHTTPHeaders: ONE_CONNECTION_PER_REQUEST });
    await use(new Robot(api));
    await api.dispose();
  },
  robot2: async ({}, use) => {
    const api = await playwrightRequest.newContext({ baseURL: control2URL, extraHTTPHeaders: ONE_CONNECTION_PER_REQUEST });
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
    async ({ cell, robot }, use, testInfo) => {
      if (!cell.robot.running) await cell.robot.restart();
      await expect.poll(async () => (await robot.tryPost("/faults/clear")), { timeout: 20_000, message: "emulator control API up" }).toBe(200);
      await robot.normalize();
      const anonymous = await playwrightRequest.newContext({ baseURL });
      await expect
        .poll(async () => (await anonymous.get("/readyz")).status(), { timeout: 20_000, message: "service connected to the robot" })
        .toBe(200);
      await anonymous.dispose();
      await use();
      if (testInfo.status !== testInfo.expectedStatus) await testInfo.attach("cell output", { body: cell.output, contentType: "text/plain" });
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

/**
 * The cell quiet again: `robots` back to running (their faults cleared, the program on) and every
 * unacknowledged alarm of both robots acknowledged (one request each, `why` its audited comment),
 * so the scenarios after a test that raised alarms start without them in the banner.
 */
export async function quietCell(robots: readonly Robot[], operatorApi: Service, why: string): Promise<void> {
  for (const r of robots) await r.normalize();
  for (const name of [settings.robotName, settings.robot2Name]) {
    const ack = await operatorApi.api.post("/api/v1/alarms/ack", { data: { robot: name, comment: why } });
    expect(ack.status(), await ack.text()).toBe(200);
  }
}

/**
 * Log `user` in for `page`'s browser context as the login form would (the same request from the
 * context, so the session cookie lands in its jar), without the form: for tests about something
 * else. The form itself is tested where logging in is the subject (04, 10, 21, 22's phone and
 * headers).
 */
export async function loggedIn(page: Page, user: { name: string; password: string }): Promise<void> {
  const answer = await page.request.post("/api/v1/auth/login", { data: { username: user.name, password: user.password } });
  expect(answer.status(), await answer.text()).toBe(200);
}

/** Take control in the panel (logged in as the operator) and see it held. */
export async function takeControl(page: Page): Promise<void> {
  await page.getByTestId("take-control").click();
  await expect(page.getByTestId("control-holder")).toHaveAttribute("data-holder", settings.operator.name);
  await expect(page.getByTestId("control-holder")).toContainText(settings.operator.name);
  await expect(page.getByTestId("release-control")).toBeVisible();
}

/** Open the panel, live, logged in as the operator (`loggedIn`). */
export async function operatorPanel(page: Page): Promise<void> {
  await loggedIn(page, settings.operator);
  await page.goto("/");
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  await expect(page.getByTestId("current-user")).toContainText(settings.operator.name);
}

/** Open the panel logged in as the operator and take control. */
export async function operatorWithControl(page: Page): Promise<void> {
  await operatorPanel(page);
  await takeControl(page);
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

/**
 * Before `page` loads anything: every WebSocket message the page receives can be noted by
 * `noteMessage` (the moment the page's handler starts on it). With `noteWhen`, that times the
 * page's own share of a change's way to the screen, which a busy machine cannot stretch the way
 * it stretches the whole way (the emulator, the service, the network), a speed figure of bench/.
 */
export async function watchMessages(page: Page): Promise<void> {
  await page.addInitScript(() => {
    const w = window as unknown as { __e2eWanted: Record<string, string>; __e2eArrived: Record<string, number> };
    w.__e2eWanted = {};
    w.__e2eArrived = {};
    const own = Object.getOwnPropertyDescriptor(WebSocket.prototype, "onmessage");
    if (own?.set === undefined || own.get === undefined) return;
    const { get, set } = own;
    Object.defineProperty(WebSocket.prototype, "onmessage", {
      configurable: true,
      enumerable: own.enumerable,
      get() {
        return get.call(this);
      },
      set(handler: ((this: WebSocket, ev: MessageEvent) => unknown) | null) {
        if (typeof handler !== "function") {
          set.call(this, handler);
          return;
        }
        set.call(this, function (this: WebSocket, ev: MessageEvent) {
          const arrived_ms = Date.now();
          if (typeof ev.data === "string") {
            for (const [name, source] of Object.entries(w.__e2eWanted)) {
              if (w.__e2eArrived[name] === undefined && new RegExp(source).test(ev.data)) w.__e2eArrived[name] = arrived_ms;
            }
          }
          return handler.call(this, ev);
        });
      },
    });
  });
}

/** From now on, note when the page first receives a WebSocket message matching `pattern`. */
export async function noteMessage(page: Page, name: string, pattern: RegExp): Promise<void> {
  await page.evaluate(
    ({ name, source }) => {
      const w = window as unknown as { __e2eWanted?: Record<string, string>; __e2eArrived?: Record<string, number> };
      if (w.__e2eWanted === undefined || w.__e2eArrived === undefined) throw new Error("watchMessages(page) before the page loads");
      delete w.__e2eArrived[name];
      w.__e2eWanted[name] = source;
    },
    { name, source: pattern.source },
  );
}

/** When the page received the message `noteMessage` named `name` (ms since the epoch). */
export async function messageAt(page: Page, name: string): Promise<number | undefined> {
  return page.evaluate((name) => (window as unknown as { __e2eArrived?: Record<string, number> }).__e2eArrived?.[name], name);
}

/**
 * Until the panel has received `frames` more frames (its joint table counts them): the data has
 * moved on, however slowly a busy machine delivers it. 100 frames are 1 s at RPI 10 ms.
 */
export async function framesFlow(page: Page, frames: number): Promise<void> {
  const table = page.getByTestId("joint-table");
  const from = Number(await table.getAttribute("data-frames"));
  await expect.poll(async () => Number(await table.getAttribute("data-frames")), { message: `${frames} more frames` }).toBeGreaterThan(from + frames);
}

/** The first robot's recording, its range on disk (`history/status`: its oldest and newest frame, s since the epoch). */
export async function recorded(request: APIRequestContext): Promise<{ first: number; last: number }> {
  const answer = await request.get(`/api/v1/robots/${settings.robotName}/history/status`);
  expect(answer.status(), await answer.text()).toBe(200);
  const { first, last } = (await answer.json()) as { first: number | null; last: number | null };
  return { first: first ?? Number.NaN, last: last ?? Number.NaN };
}

/** Until the recording holds frames up to `time_s` (the recorder writes at least every second). */
export async function recordedUntil(request: APIRequestContext, time_s: number, what: string): Promise<void> {
  await expect.poll(async () => (await recorded(request)).last, { message: what }).toBeGreaterThanOrEqual(time_s);
}
