/**
 * Debian's Mosquitto as a private broker for a scenario: anonymous, no persistence, on one
 * loopback address and port, its configuration in the scenario's state directory. Resolves once
 * it listens (it fails at once if it exits first).
 */
import { expect } from "@playwright/test";
import { spawn } from "node:child_process";
import { writeFileSync } from "node:fs";
import path from "node:path";
import { Child } from "./processes";
import { env } from "./settings";

const MOSQUITTO = env("E2E_MOSQUITTO", "/usr/sbin/mosquitto");

export async function startMosquitto(dir: string, host: string, port: number, started: (child: Child) => void): Promise<Child> {
  const config = path.join(dir, "mosquitto.conf");
  const lines = [`listener ${port} ${host}`, "allow_anonymous true", "persistence false", "log_dest stderr"];
  // As root Mosquitto drops to the user "mosquitto", who cannot read the private state directory.
  if (process.getuid?.() === 0) lines.push("user root");
  writeFileSync(config, lines.join("\n") + "\n");
  const broker = new Child("mosquitto", spawn(MOSQUITTO, ["-c", config], { stdio: ["ignore", "pipe", "pipe"] }));
  started(broker);
  await expect
    .poll(
      () => {
        if (!broker.running) throw new Error(`mosquitto exited:\n${broker.output}`);
        return broker.output.includes("Opening ipv4 listen socket");
      },
      { timeout: 20_000, message: "mosquitto listens" },
    )
    .toBe(true);
  return broker;
}
