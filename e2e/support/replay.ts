/**
 * A second, private cell for a replay scenario: `cobot-hmi emulator --replay FILE --loop` on a
 * loopback address of its own and a `cobot-hmi serve` for that one robot on a free port, both
 * started by the spec (never in the worker's cell, whose two robots other specs count) and
 * stopped by it, even when it fails.
 */
import { mkdtempSync } from "node:fs";
import path from "node:path";
import { type Child, cobotHmi, freePort } from "./processes";
import { env, ofCell, settings } from "./settings";

export type { Child };

/**
 * Clear of the worker's cell (127.0.0.1, .3, .4, .6), of `make demo` (.2) and of pytest
 * (127.10+); each worker's on its own addresses as its cell's (support/settings.ts).
 */
export const replaySettings = {
  /** The replaying emulator's EtherNet/IP target (TCP 44818, UDP 2222 on this address). */
  robotHost: ofCell(env("E2E_REPLAY_ROBOT_HOST", "127.0.0.9")),
  /** The replay service's own EtherNet/IP address (it receives T→O on UDP 2222 there). */
  localHost: ofCell(env("E2E_REPLAY_LOCAL_HOST", "127.0.0.10")),
  /** The replayed robot's name in that service. */
  robotName: env("E2E_REPLAY_ROBOT_NAME", "replayed"),
} as const;

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
  const stateDir = mkdtempSync(path.join(settings.stateDir, "replay-"));
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
  await service.waitForHttp(`${baseURL}/readyz`, 200, 60_000, "replay service connected to the replaying emulator");
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
