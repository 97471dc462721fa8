/**
 * End-to-end tests: Debian's Chromium against the real emulators and the real service, on
 * loopback, nothing mocked. Each worker starts its own cell (support/cell.ts, a worker-scoped
 * fixture): two emulated robots (an M1013 and an M0609) and the service with both as
 * `[[robots]]`, on the worker's own addresses; the tests drive the robots through the
 * emulators' control APIs. The tests of one worker share its cell, one after the other.
 */
import { defineConfig } from "@playwright/test";
import { baseURL } from "./support/settings";

/** Workers (each with its own cell): E2E_WORKERS, 2 by default (measured on a 2-core machine). */
const workers = Number(process.env.E2E_WORKERS ?? "2");

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
  globalTeardown: "./support/teardown.ts",
  // Test by test: a long scenario (09's minute of packet loss) runs beside the others.
  fullyParallel: true,
  workers,
  retries: 0,
  forbidOnly: !!process.env.CI,
  // Slack that a busy machine cannot exhaust: a green test never waits for these.
  timeout: 120_000,
  expect: { timeout: 20_000 },
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
    // A trace snapshots the page at every step of every test, failing or not: on a page that
    // redraws plots all the time that doubled a test's time. E2E_TRACE=retain-on-failure to debug.
    trace: (process.env.E2E_TRACE ?? "off") as "off" | "on" | "retain-on-failure" | "on-first-retry",
    launchOptions: { executablePath: process.env.E2E_CHROMIUM ?? "/usr/bin/chromium", args: chromiumArgs },
  },
});
