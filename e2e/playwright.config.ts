/**
 * End-to-end tests: Debian's Chromium against the real emulators and the real service, on
 * loopback, nothing mocked. Playwright's webServer starts two emulated robots (an M1013 and an
 * M0609, each under a small supervisor so that a test can kill and restart it) and the service
 * with both as `[[robots]]`; the tests drive the robots through the emulators' control APIs.
 * One worker: every test shares the same robots.
 */
import { defineConfig } from "@playwright/test";
import path from "node:path";
import {
  baseURL,
  control2URL,
  controlURL,
  E2E_DIR,
  emulator2PidFile,
  emulatorPidFile,
  serviceConfigFile,
  settings,
} from "./support/settings";

/** A shell word: the webServer commands run through /bin/sh. */
function sh(word: string | number): string {
  return `'${String(word).replaceAll("'", `'\\''`)}'`;
}

const cli = sh(settings.cobotHmi);
const stateDir = sh(settings.stateDir);

/** An emulated robot of `model` at `host`, under the supervisor that records its pid. */
const emulatorCommand = (pidFile: string, host: string, model: string) =>
  [
    "node",
    sh(path.join(E2E_DIR, "support", "emulator-supervisor.mjs")),
    sh(pidFile),
    "--",
    cli,
    "emulator",
    "--host", sh(host),
    "--tcp-port", sh(settings.robotTcpPort),
    "--udp-port", sh(settings.robotUdpPort),
    "--control-port", sh(settings.controlPort),
    "--model", sh(model),
    // Two emulators on one machine: only the service's own connections, no discovery answers.
    "--no-discovery",
  ].join(" ");

/** The service's two robots, in the TOML the service reads (the first is its default robot). */
const robotsToml = [
  "[[robots]]",
  `name = "${settings.robotName}"`,
  `host = "${settings.robotHost}"`,
  `tcp_port = ${settings.robotTcpPort}`,
  "",
  "[[robots]]",
  `name = "${settings.robot2Name}"`,
  `host = "${settings.robot2Host}"`,
  `tcp_port = ${settings.robotTcpPort}`,
];

const addUser = (user: { name: string }, role: string, passwordVar: string) =>
  `printf '%s\\n' "$${passwordVar}" | ${cli} users add ${sh(user.name)} --role ${role} --password-stdin --state-dir ${stateDir}`;

const serviceCommand = [
  `printf '%s\\n' ${robotsToml.map(sh).join(" ")} > ${sh(serviceConfigFile)}`,
  addUser(settings.operator, "operator", "E2E_OPERATOR_PASSWORD"),
  addUser(settings.viewer, "viewer", "E2E_VIEWER_PASSWORD"),
  [
    "exec",
    cli,
    "serve",
    "--config", sh(serviceConfigFile),
    "--local-host", sh(settings.localHost),
    "--local-udp-port", sh(settings.localUdpPort),
    "--rpi-ms", sh(settings.rpiMs),
    "--timeout-multiplier", sh(settings.timeoutMultiplier),
    "--host", sh(settings.httpHost),
    "--port", sh(settings.httpPort),
    "--state-dir", stateDir,
    "--frontend-dir", sh(settings.frontendDir),
  ].join(" "),
].join(" && ");

const chromiumArgs = [
  "--no-sandbox",
  "--disable-gpu",
  "--disable-background-networking",
  "--disable-component-update",
  "--no-first-run",
];

export default defineConfig({
  testDir: "./tests",
  outputDir: "./test-results",
  fullyParallel: false,
  workers: 1,
  retries: 0,
  forbidOnly: !!process.env.CI,
  timeout: 60_000,
  expect: { timeout: 10_000 },
  reporter: [
    ["list"],
    ["html", { open: "never", outputFolder: "playwright-report" }],
    ["json", { outputFile: "playwright-report/results.json" }],
  ],
  use: {
    baseURL,
    browserName: "chromium",
    headless: true,
    viewport: { width: 1600, height: 1000 },
    screenshot: "only-on-failure",
    trace: "retain-on-failure",
    launchOptions: { executablePath: process.env.E2E_CHROMIUM ?? "/usr/bin/chromium", args: chromiumArgs },
  },
  webServer: [
    {
      name: "emulator",
      command: emulatorCommand(emulatorPidFile, settings.robotHost, "M1013"),
      url: `${controlURL}/status`,
      timeout: 60_000,
      reuseExistingServer: false,
      stdout: "pipe",
      stderr: "pipe",
      gracefulShutdown: { signal: "SIGTERM", timeout: 10_000 },
    },
    {
      name: "emulator2",
      command: emulatorCommand(emulator2PidFile, settings.robot2Host, "M0609"),
      url: `${control2URL}/status`,
      timeout: 60_000,
      reuseExistingServer: false,
      stdout: "pipe",
      stderr: "pipe",
      gracefulShutdown: { signal: "SIGTERM", timeout: 10_000 },
    },
    {
      name: "service",
      command: serviceCommand,
      // /readyz answers 200 only once the class 1 connections are up: tests start on live data.
      url: `${baseURL}/readyz`,
      timeout: 60_000,
      reuseExistingServer: false,
      stdout: "pipe",
      stderr: "pipe",
      gracefulShutdown: { signal: "SIGTERM", timeout: 10_000 },
    },
  ],
});
