/**
 * A worker's cell: two emulated robots (an M1013 and an M0609, `cobot-hmi emulator`) and the
 * service with both as `[[robots]]` (`cobot-hmi serve`, serving the built frontend), on the
 * worker's own loopback addresses and HTTP port (support/settings.ts), in a state directory of
 * its own. Started once per worker (a worker-scoped fixture), so a test that kills an emulator
 * or stops a robot never disturbs another worker's tests; a worker started again after a failed
 * test gets a fresh cell.
 */
import { mkdirSync, writeFileSync } from "node:fs";
import path from "node:path";
import { type Child, cobotHmi, runCobotHmi } from "./processes";
import { baseURL, cellIndex, control2URL, controlURL, settings } from "./settings";

/** One emulated robot of the cell: a process a test may kill and start again. */
export class EmulatedRobot {
  private child: Child;

  constructor(
    readonly name: string,
    private readonly args: readonly string[],
    readonly controlURL: string,
  ) {
    this.child = cobotHmi(name, args);
  }

  get running(): boolean {
    return this.child.running;
  }

  get pid(): number {
    return this.child.pid;
  }

  get output(): string {
    return this.child.output;
  }

  /** Until its control API answers (it fails at once if the process ends first). */
  async ready(timeout_ms = 60_000): Promise<void> {
    await this.child.waitForHttp(`${this.controlURL}/status`, 200, timeout_ms, `${this.name}: control API up`);
  }

  /** SIGKILL: the robot is gone at once, as with a pulled plug. Resolves to the killed pid. */
  async kill(): Promise<number> {
    const pid = this.child.pid;
    await this.child.kill();
    return pid;
  }

  /** Start it again (nothing to do while it runs); resolves once its control API answers. */
  async restart(): Promise<number> {
    if (!this.child.running) this.child = cobotHmi(this.name, this.args);
    await this.ready();
    return this.child.pid;
  }

  stop = () => this.child.stop();
}

export class Cell {
  /** The service: the panel, the kiosk and the API. */
  readonly baseURL = baseURL;
  readonly dir: string;
  readonly robot: EmulatedRobot;
  readonly robot2: EmulatedRobot;
  private service: Child | null = null;

  constructor() {
    // A fresh directory per worker process: a worker started again after a failure starts clean.
    this.dir = path.join(settings.stateDir, `cell-${cellIndex}-worker-${process.env.TEST_WORKER_INDEX ?? "0"}`);
    mkdirSync(this.dir, { recursive: true });
    // The first robot's program marks each cycle start on bit output register 63, its cycle trigger.
    const marker = ["--cycle-marker-register", "63"];
    this.robot = new EmulatedRobot(`emulator ${settings.robotName}`, [...emulatorArgs(settings.robotHost, "M1013"), ...marker], controlURL);
    this.robot2 = new EmulatedRobot(`emulator ${settings.robot2Name}`, emulatorArgs(settings.robot2Host, "M0609"), control2URL);
  }

  /** Its output so far, for a failure's message: every process's last lines. */
  get output(): string {
    const parts = [this.robot, this.robot2, ...(this.service !== null ? [this.service] : [])];
    return parts.map((p) => `--- ${p.name} ---\n${p.output.slice(-4000)}`).join("\n");
  }

  /** Users, then the service; resolves once it is connected to both robots (`/readyz` 200). */
  async start(): Promise<void> {
    const stateDir = ["--state-dir", this.dir];
    // The users file is written by one command at a time; meanwhile the emulators start.
    await runCobotHmi("users add operator", ["users", "add", settings.operator.name, "--role", "operator", "--password-stdin", ...stateDir], `${settings.operator.password}\n`);
    await runCobotHmi("users add viewer", ["users", "add", settings.viewer.name, "--role", "viewer", "--password-stdin", ...stateDir], `${settings.viewer.password}\n`);
    const config = path.join(this.dir, "service.toml");
    writeFileSync(config, serviceToml());
    await Promise.all([this.robot.ready(), this.robot2.ready()]);
    this.service = cobotHmi("service", [
      "serve",
      "--config", config,
      "--local-host", settings.localHost,
      "--local-udp-port", String(settings.localUdpPort),
      "--rpi-ms", String(settings.rpiMs),
      "--timeout-multiplier", String(settings.timeoutMultiplier),
      "--host", settings.httpHost,
      "--port", String(settings.httpPort),
      ...stateDir,
      "--frontend-dir", settings.frontendDir,
    ]);
    // /readyz answers 200 only once the class 1 connections are up: tests start on live data.
    await this.service.waitForHttp(`${baseURL}/readyz`, 200, 90_000, "service connected to both robots");
  }

  /** The service first (it closes its connections), then the robots. */
  async stop(): Promise<void> {
    await this.service?.stop();
    await Promise.all([this.robot.stop(), this.robot2.stop()]);
  }
}

/** An emulated robot of `model` at `host`: only the service's connections, no discovery answers. */
function emulatorArgs(host: string, model: string): string[] {
  return [
    "emulator",
    "--host", host,
    "--tcp-port", String(settings.robotTcpPort),
    "--udp-port", String(settings.robotUdpPort),
    "--control-port", String(settings.controlPort),
    "--model", model,
    "--no-discovery",
  ];
}

/** The service's two robots, in the TOML the service reads (the first is its default robot). */
function serviceToml(): string {
  const robot = (name: string, host: string) => [`[[robots]]`, `name = "${name}"`, `host = "${host}"`, `tcp_port = ${settings.robotTcpPort}`, ""];
  const trigger = [`cycle_trigger = "bit_output_registers.63:rising"`, ""];
  return [...robot(settings.robotName, settings.robotHost), ...trigger, ...robot(settings.robot2Name, settings.robot2Host)].join("\n");
}
