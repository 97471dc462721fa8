/**
 * A small plant for the plant page's scenario (tests/50-plant.spec.ts), started by the spec and
 * stopped by it: Debian's Mosquitto as the plant's broker, two real cells (each an emulated
 * M1013 and `cobot-hmi serve` for it, publishing with its Sparkplug edge node to that broker,
 * group and node its own) and `cobot-hmi plant` on the broker, serving the built frontend. None
 * of it is the worker's cell (whose robots other specs count); every address is its own:
 *
 * | what | default (worker 0; worker N adds N to the third byte) | override |
 * |---|---|---|
 * | the broker (a free TCP port) | 127.0.0.20 | `E2E_PLANT_BROKER_HOST` |
 * | cell 1: emulator, the service's T→O address | 127.0.0.21, 127.0.0.22 | `E2E_PLANT_CELL1_ROBOT_HOST`, `E2E_PLANT_CELL1_LOCAL_HOST` |
 * | cell 2: emulator, the service's T→O address | 127.0.0.23, 127.0.0.24 | `E2E_PLANT_CELL2_ROBOT_HOST`, `E2E_PLANT_CELL2_LOCAL_HOST` |
 * | the services' and the plant's HTTP | free ports of `E2E_HTTP_HOST` | |
 *
 * The cells name the plant their primary host application, so they are born once its STATE
 * says it is online and it sees every birth.
 */
import { expect, type Page } from "@playwright/test";
import { spawn } from "node:child_process";
import { mkdtempSync, writeFileSync } from "node:fs";
import path from "node:path";
import { Child, cobotHmi, freePort } from "./processes";
import { env, ofCell, settings } from "./settings";

export const plantSettings = {
  brokerHost: ofCell(env("E2E_PLANT_BROKER_HOST", "127.0.0.20")),
  cells: [
    {
      group: "body-shop",
      node: "cell-1",
      robotHost: ofCell(env("E2E_PLANT_CELL1_ROBOT_HOST", "127.0.0.21")),
      localHost: ofCell(env("E2E_PLANT_CELL1_LOCAL_HOST", "127.0.0.22")),
    },
    {
      group: "paint-shop",
      node: "cell-2",
      robotHost: ofCell(env("E2E_PLANT_CELL2_ROBOT_HOST", "127.0.0.23")),
      localHost: ofCell(env("E2E_PLANT_CELL2_LOCAL_HOST", "127.0.0.24")),
    },
  ],
  robotName: "m1013",
  hostId: "cobot-hmi-plant",
} as const;

const MOSQUITTO = env("E2E_MOSQUITTO", "/usr/sbin/mosquitto");

export interface PlantCell {
  readonly group: string;
  readonly node: string;
  readonly baseURL: string;
  readonly controlURL: string;
  readonly emulator: Child;
  readonly service: Child;
}

/** The plant and its cells; `stop` ends every process it started, whatever failed. */
export class SmallPlant {
  readonly children: Child[] = [];
  readonly cells: PlantCell[] = [];
  baseURL = "";
  brokerURL = "";
  private readonly dir = mkdtempSync(path.join(settings.stateDir, "plant-"));

  get output(): string {
    return this.children.map((c) => `--- ${c.name} ---\n${c.output.slice(-4000)}`).join("\n");
  }

  private keep(child: Child): Child {
    this.children.push(child);
    return child;
  }

  async start(): Promise<void> {
    const brokerPort = await freePort(plantSettings.brokerHost);
    this.brokerURL = `mqtt://${plantSettings.brokerHost}:${brokerPort}`;
    await this.startBroker(brokerPort);
    // The emulators meanwhile: they take longest.
    const emulators = plantSettings.cells.map((cell) =>
      this.keep(
        cobotHmi(`emulator ${cell.node}`, [
          "emulator",
          "--host", cell.robotHost,
          "--tcp-port", String(settings.robotTcpPort),
          "--udp-port", String(settings.robotUdpPort),
          "--control-port", String(settings.controlPort),
          "--model", "M1013",
          "--no-discovery",
        ]),
      ),
    );
    const plantPort = await freePort(settings.httpHost);
    this.baseURL = `http://${settings.httpHost}:${plantPort}`;
    const plant = this.keep(
      cobotHmi("plant", [
        "plant",
        "--mqtt-url", this.brokerURL,
        "--host", settings.httpHost,
        "--port", String(plantPort),
        "--state-dir", path.join(this.dir, "plant"),
        "--frontend-dir", settings.frontendDir,
      ]),
    );
    await plant.waitForHttp(`${this.baseURL}/healthz`, 200, 60_000, "the plant connected to its broker");
    for (const [i, cell] of plantSettings.cells.entries()) {
      const controlURL = `http://${cell.robotHost}:${settings.controlPort}`;
      await emulators[i]!.waitForHttp(`${controlURL}/status`, 200, 60_000, `${cell.node}: emulator up`);
      const port = await freePort(settings.httpHost);
      const baseURL = `http://${settings.httpHost}:${port}`;
      const service = this.keep(
        cobotHmi(`service ${cell.node}`, [
          "serve",
          "--robot", cell.robotHost,
          "--robot-name", plantSettings.robotName,
          "--local-host", cell.localHost,
          "--local-udp-port", String(settings.localUdpPort),
          "--rpi-ms", String(settings.rpiMs),
          "--timeout-multiplier", String(settings.timeoutMultiplier),
          "--host", settings.httpHost,
          "--port", String(port),
          "--state-dir", path.join(this.dir, cell.node),
          "--frontend-dir", settings.frontendDir,
          "--mqtt-url", this.brokerURL,
          "--sparkplug-group", cell.group,
          "--sparkplug-node", cell.node,
          "--sparkplug-primary-host", plantSettings.hostId,
        ]),
      );
      this.cells.push({ group: cell.group, node: cell.node, baseURL, controlURL, emulator: emulators[i]!, service });
    }
    for (const cell of this.cells) {
      await cell.service.waitForHttp(`${cell.baseURL}/readyz`, 200, 90_000, `${cell.node}: connected to its robot`);
    }
  }

  private async startBroker(port: number): Promise<void> {
    const config = path.join(this.dir, "mosquitto.conf");
    const lines = [`listener ${port} ${plantSettings.brokerHost}`, "allow_anonymous true", "persistence false", "log_dest stderr"];
    // As root Mosquitto drops to the user "mosquitto", who cannot read the private state directory.
    if (process.getuid?.() === 0) lines.push("user root");
    writeFileSync(config, lines.join("\n") + "\n");
    const broker = this.keep(new Child("mosquitto", spawn(MOSQUITTO, ["-c", config], { stdio: ["ignore", "pipe", "pipe"] })));
    await expect
      .poll(
        async () => {
          if (!broker.running) throw new Error(`mosquitto exited:\n${broker.output}`);
          return broker.output.includes("Opening ipv4 listen socket");
        },
        { timeout: 20_000, message: "mosquitto listens" },
      )
      .toBe(true);
  }

  /** The services first (their edge nodes' deaths go out), then the plant, the emulators, the broker. */
  async stop(): Promise<void> {
    const order = [...this.children].reverse();
    for (const child of order) await child.stop();
  }
}

/**
 * Before the page loads: note when the page's own fetches answer with a body matching a pattern
 * (`noteAnswer`), the moment its code gets the text. The plant page is live by polling, so this
 * is where a change reaches the page, as `watchMessages` is for the panel's stream.
 */
export async function watchAnswers(page: Page): Promise<void> {
  await page.addInitScript(() => {
    const w = window as unknown as { __e2eWanted: Record<string, string>; __e2eArrived: Record<string, number> };
    w.__e2eWanted = {};
    w.__e2eArrived = {};
    const text = Response.prototype.text;
    const json = Response.prototype.json;
    const note = (body: string) => {
      const arrived_ms = Date.now();
      for (const [name, source] of Object.entries(w.__e2eWanted)) {
        if (w.__e2eArrived[name] === undefined && new RegExp(source).test(body)) w.__e2eArrived[name] = arrived_ms;
      }
    };
    Response.prototype.text = async function (this: Response) {
      const body = await text.call(this);
      note(body);
      return body;
    };
    Response.prototype.json = async function (this: Response) {
      const body = await text.call(this);
      note(body);
      return JSON.parse(body) as unknown;
    };
    void json;
  });
}

/** From now on, note when the page first gets an answer matching `pattern`. */
export async function noteAnswer(page: Page, name: string, pattern: RegExp): Promise<void> {
  await page.evaluate(
    ({ name, source }) => {
      const w = window as unknown as { __e2eWanted?: Record<string, string>; __e2eArrived?: Record<string, number> };
      if (w.__e2eWanted === undefined || w.__e2eArrived === undefined) throw new Error("watchAnswers(page) before the page loads");
      delete w.__e2eArrived[name];
      w.__e2eWanted[name] = source;
    },
    { name, source: pattern.source },
  );
}

/** When the page got the answer `noteAnswer` named `name` (ms since the epoch). */
export async function answerAt(page: Page, name: string): Promise<number | undefined> {
  return page.evaluate((name) => (window as unknown as { __e2eArrived?: Record<string, number> }).__e2eArrived?.[name], name);
}

/** Note when the element `selector` first has `attribute` = `value` (read with `shownAt`). */
export async function noteShown(page: Page, name: string, selector: string, attribute: string, value: string): Promise<void> {
  await page.locator(selector).waitFor();
  await page.evaluate(
    ({ name, selector, attribute, value }) => {
      const w = window as unknown as { __e2eTimes?: Record<string, number> };
      const times = (w.__e2eTimes ??= {});
      delete times[name];
      const observer = new MutationObserver(() => {
        const el = document.querySelector(selector);
        if (times[name] === undefined && el !== null && el.getAttribute(attribute) === value) {
          times[name] = Date.now();
          observer.disconnect();
        }
      });
      observer.observe(document.body, { attributes: true, childList: true, subtree: true });
    },
    { name, selector, attribute, value },
  );
}

export async function shownAt(page: Page, name: string): Promise<number | undefined> {
  return page.evaluate((name) => (window as unknown as { __e2eTimes?: Record<string, number> }).__e2eTimes?.[name], name);
}
