/**
 * Where the end-to-end run puts things: one place, read from the environment with defaults
 * that stay clear of `make demo` (emulator 127.0.0.2, service 127.0.0.1:8000) and of pytest's
 * per-process loopback addresses (127.10.x.x and up).
 *
 * Each Playwright worker runs its own cell (support/cell.ts: two emulated robots and a service),
 * so that a test killing an emulator or stopping a robot disturbs no other worker's tests: the
 * worker's parallel index (0, 1, …) is added to the third byte of every loopback address and to
 * the HTTP port. Worker 0 keeps the addresses below (127.0.0.3, …, port 8100), worker 1 has
 * 127.0.1.3, …, port 8101.
 *
 * The Playwright config computes the state directory and the passwords once in the runner
 * process and exports them into `process.env`, so the worker processes (which inherit the
 * runner's environment) see the same ones.
 */
import { mkdtempSync } from "node:fs";
import { tmpdir } from "node:os";
import path from "node:path";
import { randomBytes } from "node:crypto";
import { fileURLToPath } from "node:url";

export const E2E_DIR = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "..");
export const REPO_DIR = path.resolve(E2E_DIR, "..");

export function env(name: string, fallback: string): string {
  const value = process.env[name];
  return value === undefined || value === "" ? fallback : value;
}

function envNumber(name: string, fallback: number): number {
  const text = env(name, String(fallback));
  const value = Number(text);
  if (!Number.isFinite(value)) throw new Error(`${name}: expected a number, got ${JSON.stringify(text)}`);
  return value;
}

/** The worker's cell: its parallel index (Playwright sets it before loading config and tests). */
export const cellIndex = Number(process.env.TEST_PARALLEL_INDEX ?? "0");

/** A loopback address of this worker's cell: `host` with the cell's index added to its third byte. */
export function ofCell(host: string): string {
  const bytes = host.split(".").map(Number);
  if (bytes.length !== 4 || bytes[0] !== 127 || !bytes.every((b) => Number.isInteger(b) && b >= 0 && b <= 255)) {
    throw new Error(`${host}: expected a loopback IPv4 address (127.x.y.z)`);
  }
  const third = bytes[2]! + cellIndex;
  if (third > 255) throw new Error(`${host}: no room for the address of cell ${cellIndex}`);
  return [127, bytes[1], third, bytes[3]].join(".");
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
  robotHost: ofCell(env("E2E_ROBOT_HOST", "127.0.0.3")),
  robotTcpPort: envNumber("E2E_ROBOT_TCP_PORT", 44818),
  robotUdpPort: envNumber("E2E_ROBOT_UDP_PORT", 2222),
  controlPort: envNumber("E2E_CONTROL_PORT", 8081),
  /** The second emulated robot (an M0609), the same ports on its own address. */
  robot2Name: env("E2E_ROBOT2_NAME", "m0609"),
  robot2Host: ofCell(env("E2E_ROBOT2_HOST", "127.0.0.6")),
  /** The service's own EtherNet/IP address (it receives T→O on UDP 2222 there). */
  localHost: ofCell(env("E2E_LOCAL_HOST", "127.0.0.4")),
  localUdpPort: envNumber("E2E_LOCAL_UDP_PORT", 2222),
  /** The service's HTTP address: the panel, the kiosk and the API. */
  httpHost: env("E2E_HTTP_HOST", "127.0.0.1"),
  httpPort: envNumber("E2E_HTTP_PORT", 8100) + cellIndex,
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
  /** Fresh for each run: each cell's users file, database and recording in a directory of its own. */
  stateDir: once("E2E_STATE_DIR", () => {
    // Made here, so removed at the end of the run (support/teardown.ts); a directory given in
    // E2E_STATE_DIR is the caller's own and stays.
    process.env.E2E_STATE_DIR_MADE = "1";
    return mkdtempSync(path.join(tmpdir(), "cobot-hmi-e2e-"));
  }),
  operator: { name: "e2e-operator", password: once("E2E_OPERATOR_PASSWORD", () => randomBytes(12).toString("hex")) },
  viewer: { name: "e2e-viewer", password: once("E2E_VIEWER_PASSWORD", () => randomBytes(12).toString("hex")) },
} as const;

export const baseURL = `http://${settings.httpHost}:${settings.httpPort}`;
export const controlURL = `http://${settings.robotHost}:${settings.controlPort}`;
export const control2URL = `http://${settings.robot2Host}:${settings.controlPort}`;

/** The connection timeout the service's Forward Open asks for, in ms. */
export const connectionTimeoutMs = settings.rpiMs * (4 << settings.timeoutMultiplier);
