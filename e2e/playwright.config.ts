/**
 * End-to-end tests: Debian's Chromium against the real emulator and the real service, on
 * loopback, nothing mocked. Playwright's webServer starts both (the emulator under a small
 * supervisor so that a test can kill and restart it), and the tests drive the robot through
 * the emulator's control API. One worker: every test shares the one emulator.
 */
import { defineConfig } from "@playwright/test";
import path from "node:path";
import { baseURL, controlURL, E2E_DIR, emulatorPidFile, settings } from "./support/settings";

/** A shell word: the webServer commands run through /bin/sh. */
function sh(word: string | number): string {
  return `'${String(word).replaceAll("'", `'\\''`)}'`;
}

const cli = sh(settings.cobotHmi);
const stateDir = sh(settings.stateDir);

const emulatorCommand = [
  "node",
  sh(path.join(E2E_DIR, "support", "emulator-supervisor.mjs")),
  sh(emulatorPidFile),
  "--",
  cli,
  "emulator",
  "--host", sh(settings.robotHost),
  "--tcp-port", sh(settings.robotTcpPort),
  "--udp-port", sh(settings.robotUdpPort),
  "--control-port", sh(settings.controlPort),
].join(" ");

const addUser = (user: { name: string }, role: string, passwordVar: string) =>
  `printf '%s\\n' "$${passwordVar}" | ${cli} users add ${sh(user.name)} --role ${role} --password-stdin --state-dir ${stateDir}`;

const serviceCommand = [
  addUser(settings.operator, "operator", "E2E_OPERATOR_PASSWORD"),
  addUser(settings.viewer, "viewer", "E2E_VIEWER_PASSWORD"),
  [
    "exec",
    cli,
    "serve",
    "--robot", sh(settings.robotHost),
    "--robot-tcp-port", sh(settings.robotTcpPort),
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
      command: emulatorCommand,
      url: `${controlURL}/status`,
      timeout: 60_000,
      reuseExistingServer: false,
      stdout: "pipe",
      stderr: "pipe",
      gracefulShutdown: { signal: "SIGTERM", timeout: 10_000 },
    },
    {
      name: "service",
      command: serviceCommand,
      // /readyz answers 200 only once the class 1 connection is up: tests start on live data.
      url: `${baseURL}/readyz`,
      timeout: 60_000,
      reuseExistingServer: false,
      stdout: "pipe",
      stderr: "pipe",
      gracefulShutdown: { signal: "SIGTERM", timeout: 10_000 },
    },
  ],
});
