/**
 * Processes the tests start themselves: `cobot-hmi` commands (emulators, services) as children
 * of a Playwright worker, their output kept for a failure's message, stopped even when a test
 * fails.
 */
import { expect } from "@playwright/test";
import { spawn, type ChildProcess } from "node:child_process";
import { createServer } from "node:net";
import { settings } from "./settings";

/** Every child still running, killed should the worker exit without stopping them. */
const running = new Set<ChildProcess>();
process.once("exit", () => {
  for (const child of running) child.kill("SIGKILL");
});

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

/** A child process of the worker, its output kept for the failure message. */
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
    running.add(process);
    this.exited = new Promise((resolve) => {
      const done = () => {
        running.delete(process);
        resolve();
      };
      if (process.exitCode !== null || process.signalCode !== null) done();
      else process.once("exit", done);
    });
  }

  get running(): boolean {
    return this.process.exitCode === null && this.process.signalCode === null;
  }

  get pid(): number {
    return this.process.pid ?? -1;
  }

  /** Until its output shows `text` (it fails at once if the process ends first; a process starting on a machine at load 40 took over 30 s). */
  async waitFor(text: string, timeout_ms = 90_000): Promise<void> {
    await expect
      .poll(() => {
        if (!this.running && !this.output.includes(text)) throw new Error(`${this.name} exited:\n${this.output}`);
        return this.output.includes(text);
      }, { timeout: timeout_ms, message: `${this.name} says ${JSON.stringify(text)}` })
      .toBe(true);
  }

  /** Until `url` answers `status` (it fails at once if the process ends first). */
  async waitForHttp(url: string, status: number, timeout_ms: number, message: string): Promise<void> {
    await expect
      .poll(
        async () => {
          if (!this.running) throw new Error(`${this.name} exited:\n${this.output}`);
          try {
            return (await fetch(url)).status;
          } catch {
            return 0; // not listening yet
          }
        },
        { timeout: timeout_ms, message },
      )
      .toBe(status);
  }

  /** SIGKILL, as a crash or a pulled plug; resolves once it is gone. */
  async kill(): Promise<void> {
    if (this.running) this.process.kill("SIGKILL");
    await this.exited;
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
export function cobotHmi(name: string, args: readonly string[], stdin?: string): Child {
  const child = spawn(settings.cobotHmi, args, {
    stdio: [stdin === undefined ? "ignore" : "pipe", "pipe", "pipe"],
    env: { ...process.env, PYTHONUNBUFFERED: "1" },
  });
  if (stdin !== undefined) child.stdin?.end(stdin);
  return new Child(name, child);
}

/** Run `cobot-hmi ARGS` to its end; it must succeed. */
export async function runCobotHmi(name: string, args: readonly string[], stdin?: string): Promise<void> {
  const child = cobotHmi(name, args, stdin);
  // "close": its output read to the end too (a child cannot have closed before this line runs).
  const code = await new Promise<number | null>((resolve) => child.process.once("close", (c) => resolve(c)));
  if (code !== 0) throw new Error(`${name} failed (${code}):\n${child.output}`);
}
