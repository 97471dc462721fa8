/**
 * A second, private cell for a replay scenario: `cobot-hmi emulator --replay FILE --loop` on a
 * loopback address of its own and a `cobot-hmi serve` for that one robot on a free port, both
 * started by the spec (never by the shared webServer, whose two robots other specs count) and
 * stopped by it, even when it fails.
 */
import { expect } from "@playwright/test";
import { spawn, type ChildProcess } from "node:child_process";
import { mkdtempSync } from "node:fs";
import { createServer } from "node:net";
import { tmpdir } from "node:os";
import path from "node:path";
import { settings } from "./settings";

function env(name: string, fallback: string): string {
  const value = process.env[name];
  return value === undefined || value === "" ? fallback : value;
}

/** Clear of the shared cell (127.0.0.1, .3, .4, .6), of `make demo` (.2) and of pytest (127.10+). */
export const replaySettings = {
  /** The replaying emulator's EtherNet/IP target (TCP 44818, UDP 2222 on this address). */
  robotHost: env("E2E_REPLAY_ROBOT_HOST", "127.0.0.9"),
  /** The replay service's own EtherNet/IP address (it receives T→O on UDP 2222 there). */
  localHost: env("E2E_REPLAY_LOCAL_HOST", "127.0.0.10"),
  /** The replayed robot's name in that service. */
  robotName: env("E2E_REPLAY_ROBOT_NAME", "replayed"),
} as const;

/** A TCP port free on `host` right now. */
export async function freePort(host: string): Promise<number> {
  return new Promise((resolve, reject) => {
    const server = createServer();
    server.once("error", reject);
    server.listen(0, host, () => {
      const address = server.address();
      const port = typeof address === "object" && address !== null ? address.port : 0;
      server.close(() => resolve(port));
    });
  });
}

/** A child process of the spec, its output kept for the failure message. */
export class Child {
  output = "";
  private readonly exited: Promise<void>;

  constructor(
    readonly name: string,
    readonly process: ChildProcess,
  ) {
    const keep = (chunk: Buffer) => {
      this.output = (this.output + chunk.toString()).slice(-20_000);
    };
    process.stdout?.on("data", keep);
    process.stderr?.on("data", keep);
    this.exited = new Promise((resolve) => {
      if (process.exitCode !== null || process.signalCode !== null) resolve();
      else process.once("exit", () => resolve());
    });
  }

  get running(): boolean {
    return this.process.exitCode === null && this.process.signalCode === null;
  }

  /** Until its output shows `text` (it fails at once if the process ends first). */
  async waitFor(text: string, timeout_ms = 30_000): Promise<void> {
    await expect
      .poll(() => {
        if (!this.running && !this.output.includes(text)) throw new Error(`${this.name} exited:\n${this.output}`);
        return this.output.includes(text);
      }, { timeout: timeout_ms, message: `${this.name} says ${JSON.stringify(text)}` })
      .toBe(true);
  }

  /** SIGTERM, then SIGKILL if it has not stopped within 10 s. */
  async stop(): Promise<void> {
    if (!this.running) return;
    this.process.kill("SIGTERM");
    const timer = setTimeout(() => this.process.kill("SIGKILL"), 10_000);
    await this.exited;
    clearTimeout(timer);
  }
}

/** `cobot-hmi ARGS` as a child process (the repository's virtual environment by default). */
export function cobotHmi(name: string, args: string[]): Child {
  const child = spawn(settings.cobotHmi, args, {
    stdio: ["ignore", "pipe", "pipe"],
    env: { ...process.env, PYTHONUNBUFFERED: "1" },
  });
  return new Child(name, child);
}

export interface ReplayCell {
  readonly baseURL: string;
  readonly emulator: Child;
  readonly service: Child;
  stop(): Promise<void>;
}

/**
 * Replay `recording` (MCAP or Parquet) with `--loop` and serve that robot; resolves once the
 * service's class 1 connection is up (`/readyz` 200). `started` gets each process as soon as
 * it exists, so the caller can stop it even when this fails.
 */
export async function startReplayCell(recording: string, started: (child: Child) => void): Promise<ReplayCell> {
  const emulator = cobotHmi("replay emulator", [
    "emulator",
    "--replay", recording,
    "--loop",
    "--host", replaySettings.robotHost,
    "--no-discovery",
  ]);
  started(emulator);
  await emulator.waitFor("EtherNet/IP target on");
  const stateDir = mkdtempSync(path.join(tmpdir(), "cobot-hmi-e2e-replay-"));
  const port = await freePort(settings.httpHost);
  const service = cobotHmi("replay service", [
    "serve",
    "--robot", replaySettings.robotHost,
    "--robot-name", replaySettings.robotName,
    "--local-host", replaySettings.localHost,
    "--rpi-ms", String(settings.rpiMs),
    "--timeout-multiplier", String(settings.timeoutMultiplier),
    "--host", settings.httpHost,
    "--port", String(port),
    "--state-dir", stateDir,
    "--frontend-dir", settings.frontendDir,
  ]);
  started(service);
  const baseURL = `http://${settings.httpHost}:${port}`;
  await expect
    .poll(
      async () => {
        if (!service.running) throw new Error(`replay service exited:\n${service.output}`);
        try {
          return (await fetch(`${baseURL}/readyz`)).status;
        } catch {
          return 0; // not listening yet
        }
      },
      { timeout: 60_000, message: "replay service connected to the replaying emulator" },
    )
    .toBe(200);
  return {
    baseURL,
    emulator,
    service,
    stop: async () => {
      await service.stop();
      await emulator.stop();
    },
  };
}
