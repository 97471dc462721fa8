/**
 * A private cell for the robot-health scenario (44): an emulated M1013 running its demo program
 * with its cycle marker, on a loopback address of its own, and a `cobot-hmi serve` for that one
 * robot on a free port, with its own users and database, started by the spec and stopped by it.
 * The service opens both of the plant's doors: a Sparkplug B edge node on a Mosquitto of the
 * cell's own, and an OPC UA server; `startHealthPeer` reads both (support/health_peer.py).
 * Health counts knocks per shift and keeps every baseline: in the worker's cell those would stay
 * for every later spec (an advisory alarm the others' banners would show), so it gets a cell
 * that ends with it.
 */
import { expect } from "@playwright/test";
import { spawn } from "node:child_process";
import { mkdtempSync, writeFileSync } from "node:fs";
import path from "node:path";
import { startMosquitto } from "./mosquitto";
import { Child, cobotHmi, freePort, runCobotHmi } from "./processes";
import { E2E_DIR, env, ofCell, settings } from "./settings";

export type { Child };

/** Clear of the worker's cell (.1, .3, .4, .6), the replay cell (.9, .10), the plant (.20–.24), `make demo` (.2) and pytest (127.10+). */
export const healthSettings = {
  /** The emulated robot's EtherNet/IP target and control API (on settings.controlPort). */
  robotHost: ofCell(env("E2E_HEALTH_ROBOT_HOST", "127.0.0.11")),
  /** The service's own EtherNet/IP address (it receives T→O on UDP 2222 there). */
  localHost: ofCell(env("E2E_HEALTH_LOCAL_HOST", "127.0.0.12")),
  robotName: env("E2E_HEALTH_ROBOT_NAME", "worn"),
  /** The cell's own broker (Mosquitto, a free TCP port) and the service's OPC UA server (a free TCP port). */
  brokerHost: ofCell(env("E2E_HEALTH_BROKER_HOST", "127.0.0.13")),
  opcuaHost: ofCell(env("E2E_HEALTH_OPCUA_HOST", "127.0.0.14")),
  sparkplugGroup: "e2e-health",
  sparkplugNode: "health-cell",
  /**
   * The verdicts judged every second and a trend snapshot every 2 s (the defaults, 5 s and
   * 10 min, are a plant's): the page shows a change within a test's patience.
   */
  reportEvery_s: 1,
  snapshotEvery_s: 2,
} as const;

export interface HealthCell {
  readonly baseURL: string;
  readonly controlURL: string;
  readonly brokerAddress: string;
  readonly opcuaURL: string;
  readonly emulator: Child;
  readonly service: Child;
}

/**
 * Start the robot and its service; resolves once the service's class 1 connection is up
 * (`/readyz` 200). `started` gets each process as soon as it exists, so the caller can stop it
 * even when this fails. The worker's operator and viewer (settings.operator, .viewer) are its
 * users too.
 */
export async function startHealthCell(started: (child: Child) => void): Promise<HealthCell> {
  const dir = mkdtempSync(path.join(settings.stateDir, "health-"));
  const emulator = cobotHmi("health emulator", [
    "emulator",
    "--host", healthSettings.robotHost,
    "--tcp-port", String(settings.robotTcpPort),
    "--udp-port", String(settings.robotUdpPort),
    "--control-port", String(settings.controlPort),
    "--model", "M1013",
    "--no-discovery",
    // The program marks each cycle's start on bit output register 63, the service's cycle trigger.
    "--cycle-marker-register", "63",
    // Every frame a fresh measurement (the controller's 100 ms refresh is the default): a
    // baseline of two cycles then has enough friction cells to compare with.
    "--kinematic-refresh-ms", "0",
    // The motors held at room temperature: the engine compares friction within 2 °C bands of
    // the motor's temperature, and a fresh emulator's motors warm for about ten minutes after
    // the baseline, so a friction wear would not read within the test (docs/emulator.md).
    "--motor-temperature-rise-c", "0",
  ]);
  started(emulator);
  const stateDir = ["--state-dir", dir];
  await runCobotHmi("users add operator", ["users", "add", settings.operator.name, "--role", "operator", "--password-stdin", ...stateDir], `${settings.operator.password}\n`);
  await runCobotHmi("users add viewer", ["users", "add", settings.viewer.name, "--role", "viewer", "--password-stdin", ...stateDir], `${settings.viewer.password}\n`);
  const config = path.join(dir, "service.toml");
  writeFileSync(
    config,
    [
      "[[robots]]",
      `name = "${healthSettings.robotName}"`,
      `host = "${healthSettings.robotHost}"`,
      `tcp_port = ${settings.robotTcpPort}`,
      `cycle_trigger = "bit_output_registers.63:rising"`,
      "",
    ].join("\n"),
  );
  const controlURL = `http://${healthSettings.robotHost}:${settings.controlPort}`;
  await emulator.waitForHttp(`${controlURL}/status`, 200, 60_000, "health emulator: control API up");
  const brokerPort = await freePort(healthSettings.brokerHost);
  await startMosquitto(dir, healthSettings.brokerHost, brokerPort, started);
  const brokerAddress = `${healthSettings.brokerHost}:${brokerPort}`;
  const opcuaURL = `opc.tcp://${healthSettings.opcuaHost}:${await freePort(healthSettings.opcuaHost)}`;
  const port = await freePort(settings.httpHost);
  const service = cobotHmi("health service", [
    "serve",
    "--config", config,
    "--local-host", healthSettings.localHost,
    "--local-udp-port", String(settings.localUdpPort),
    "--rpi-ms", String(settings.rpiMs),
    "--timeout-multiplier", String(settings.timeoutMultiplier),
    "--health-report-s", String(healthSettings.reportEvery_s),
    "--health-snapshot-s", String(healthSettings.snapshotEvery_s),
    "--host", settings.httpHost,
    "--port", String(port),
    ...stateDir,
    "--frontend-dir", settings.frontendDir,
    "--mqtt-url", `mqtt://${brokerAddress}`,
    "--sparkplug-group", healthSettings.sparkplugGroup,
    "--sparkplug-node", healthSettings.sparkplugNode,
    "--opcua-url", opcuaURL,
  ]);
  started(service);
  const baseURL = `http://${settings.httpHost}:${port}`;
  await service.waitForHttp(`${baseURL}/readyz`, 200, 120_000, "health service connected to its robot");
  return { baseURL, controlURL, brokerAddress, opcuaURL, emulator, service };
}

/** What the peer reads at each door: metric name (`Health/J3/Verdict`, …) to value. */
export interface DoorReadings {
  readonly sparkplug: Record<string, unknown>;
  readonly opcua: Record<string, unknown>;
}

/**
 * An independent reader of the robot's health at both doors (support/health_peer.py, run with
 * the python beside `cobot-hmi`): `readings()` is the last it printed.
 */
export class HealthPeer {
  constructor(readonly child: Child) {}

  readings(): DoorReadings {
    const lines = this.child.output.split("\n");
    for (let i = lines.length - 1; i >= 0; i--) {
      if (!lines[i]!.startsWith("{")) continue;
      try {
        return JSON.parse(lines[i]!) as DoorReadings;
      } catch {
        // a line still being written: the one before
      }
    }
    return { sparkplug: {}, opcua: {} };
  }

  /** Until `name` reads a value matching `pattern` at both doors. */
  async waitForBoth(name: string, pattern: RegExp, timeout_ms = 60_000): Promise<void> {
    await expect
      .poll(
        () => {
          if (!this.child.running) throw new Error(`health peer exited:\n${this.child.output}`);
          const { sparkplug, opcua } = this.readings();
          // The reason beside a verdict, so that a failure says why the engine judged so.
          const reason = opcua[name.replace(/Verdict$/, "Reason")];
          return { sparkplug: String(sparkplug[name]), opcua: String(opcua[name]), reason };
        },
        { timeout: timeout_ms, message: `${name} at both doors matches ${pattern}` },
      )
      .toEqual(expect.objectContaining({ sparkplug: expect.stringMatching(pattern), opcua: expect.stringMatching(pattern) }));
  }
}

export function startHealthPeer(cell: HealthCell, started: (child: Child) => void): HealthPeer {
  const python = path.join(path.dirname(settings.cobotHmi), "python");
  const script = path.join(E2E_DIR, "support", "health_peer.py");
  const child = new Child(
    "health peer",
    spawn(
      python,
      [
        script,
        "--mqtt", cell.brokerAddress,
        "--group", healthSettings.sparkplugGroup,
        "--node", healthSettings.sparkplugNode,
        "--opcua", cell.opcuaURL,
        "--robot", healthSettings.robotName,
      ],
      { stdio: ["ignore", "pipe", "pipe"], env: { ...process.env, PYTHONUNBUFFERED: "1" } },
    ),
  );
  started(child);
  return new HealthPeer(child);
}
