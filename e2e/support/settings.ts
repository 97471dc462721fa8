/**
 * Where the end-to-end run puts things: one place, read from the environment with defaults
 * that stay clear of `make demo` (emulator 127.0.0.2, service 127.0.0.1:8000) and of pytest's
 * per-process loopback addresses (127.10.x.x and up).
 *
 * The Playwright config computes these once in the runner process and exports them into
 * `process.env`, so the worker processes (which inherit the runner's environment) see the same
 * temporary directory and passwords.
 */
import { mkdtempSync } from "node:fs";
import { tmpdir } from "node:os";
import path from "node:path";
import { randomBytes } from "node:crypto";
import { fileURLToPath } from "node:url";

export const E2E_DIR = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "..");
export const REPO_DIR = path.resolve(E2E_DIR, "..");

function env(name: string, fallback: string): string {
  const value = process.env[name];
  return value === undefined || value === "" ? fallback : value;
}

function envNumber(name: string, fallback: number): number {
  const text = env(name, String(fallback));
  const value = Number(text);
  if (!Number.isFinite(value)) throw new Error(`${name}: expected a number, got ${JSON.stringify(text)}`);
  return value;
}

/** Once per run (runner process): a state directory and passwords, shared through the env. */
function once(name: string, make: () => string): string {
  const value = process.env[name];
  if (value !== undefined && value !== "") return value;
  const made = make();
  process.env[name] = made;
  return made;
}

export const settings = {
  /**
   * The first emulated robot (an M1013, the service's default robot): its name in the service,
   * its EtherNet/IP target (TCP 44818, UDP 2222) and its control API.
   */
  robotName: env("E2E_ROBOT_NAME", "m1013"),
  robotHost: env("E2E_ROBOT_HOST", "127.0.0.3"),
  robotTcpPort: envNumber("E2E_ROBOT_TCP_PORT", 44818),
  robotUdpPort: envNumber("E2E_ROBOT_UDP_PORT", 2222),
  controlPort: envNumber("E2E_CONTROL_PORT", 8081),
  /** The second emulated robot (an M0609), the same ports on its own address. */
  robot2Name: env("E2E_ROBOT2_NAME", "m0609"),
  robot2Host: env("E2E_ROBOT2_HOST", "127.0.0.6"),
  /** The service's own EtherNet/IP address (it receives T→O on UDP 2222 there). */
  localHost: env("E2E_LOCAL_HOST", "127.0.0.4"),
  localUdpPort: envNumber("E2E_LOCAL_UDP_PORT", 2222),
  /** The service's HTTP address: the panel, the kiosk and the API. */
  httpHost: env("E2E_HTTP_HOST", "127.0.0.1"),
  httpPort: envNumber("E2E_HTTP_PORT", 8100),
  rpiMs: envNumber("E2E_RPI_MS", 10),
  /**
   * The service's connection timeout is RPI × (4 << multiplier) (ODVA, Forward Open): 4 gives
   * 640 ms at RPI 10 ms. The product's default (2, 160 ms) times out on this shared 2-core
   * machine when Chromium, the service and the emulator all want the CPU at once.
   */
  timeoutMultiplier: envNumber("E2E_TIMEOUT_MULTIPLIER", 4),
  /** The `cobot-hmi` command (the repository's virtual environment by default). */
  cobotHmi: env("E2E_COBOT_HMI", path.join(REPO_DIR, ".venv", "bin", "cobot-hmi")),
  /** The built frontend the service serves. */
  frontendDir: env("E2E_FRONTEND_DIR", path.join(REPO_DIR, "frontend", "dist")),
  /** Users file, audit database and the emulator's pid file, fresh for each run. */
  stateDir: once("E2E_STATE_DIR", () => mkdtempSync(path.join(tmpdir(), "cobot-hmi-e2e-"))),
  operator: { name: "e2e-operator", password: once("E2E_OPERATOR_PASSWORD", () => randomBytes(12).toString("hex")) },
  viewer: { name: "e2e-viewer", password: once("E2E_VIEWER_PASSWORD", () => randomBytes(12).toString("hex")) },
} as const;

export const baseURL = `http://${settings.httpHost}:${settings.httpPort}`;
export const controlURL = `http://${settings.robotHost}:${settings.controlPort}`;
export const control2URL = `http://${settings.robot2Host}:${settings.controlPort}`;
export const emulatorPidFile = path.join(settings.stateDir, "emulator.json");
export const emulator2PidFile = path.join(settings.stateDir, "emulator2.json");
/** The service's settings file: its two robots as `[[robots]]` tables. */
export const serviceConfigFile = path.join(settings.stateDir, "service.toml");

/** The connection timeout the service's Forward Open asks for, in ms. */
export const connectionTimeoutMs = settings.rpiMs * (4 << settings.timeoutMultiplier);
