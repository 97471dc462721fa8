// HTTPS without a proxy (issue 25): `cobot-hmi demo --tls` (its own emulator, a self-signed
// certificate made in its state directory) and Chromium told to accept that certificate, as a
// user does after comparing the fingerprint the demo printed with the one the browser shows.
// The panel loads over HTTPS, its live data comes over WSS, the session cookie is Secure and
// every answer carries HSTS.
import { expect, test } from "@playwright/test";
import { mkdirSync } from "node:fs";
import path from "node:path";
import { connect as tlsConnect } from "node:tls";
import { type Child, cobotHmi, freePort } from "../support/processes";
import { cellIndex, env, ofCell, settings } from "../support/settings";

test.use({ ignoreHTTPSErrors: true });

let demo: Child | null = null;

test.afterEach(async () => {
  await demo?.stop();
  demo = null;
});

/** The SHA-256 fingerprint of the certificate served at host:port (AB:CD:… as browsers show it). */
async function servedFingerprint(host: string, port: number): Promise<string> {
  return new Promise((resolve, reject) => {
    const socket = tlsConnect({ host, port, rejectUnauthorized: false }, () => {
      resolve(socket.getPeerCertificate().fingerprint256);
      socket.end();
    });
    socket.once("error", reject);
  });
}

test("the panel over HTTPS and WSS with the demo's self-signed certificate", async ({ page }) => {
  // A demo of its own starts (its emulator, the service) before anything: its waits alone may
  // take the suite's 120 s on a busy machine.
  test.setTimeout(300_000);
  const robotHost = ofCell(env("E2E_HTTPS_ROBOT_HOST", "127.0.0.9"));
  const localHost = ofCell(env("E2E_HTTPS_LOCAL_HOST", "127.0.0.10"));
  const httpHost = settings.httpHost;
  const port = await freePort(httpHost);
  const stateDir = path.join(settings.stateDir, `https-${cellIndex}-${Date.now()}`);
  mkdirSync(stateDir, { recursive: true });
  demo = cobotHmi("demo --tls", [
    "demo", "--tls",
    "--robots", "1",
    "--robot-host", robotHost,
    "--control-port", "0",
    "--local-host", localHost,
    "--host", httpHost,
    "--port", String(port),
    "--state-dir", stateDir,
    "--frontend-dir", settings.frontendDir,
  ]);
  await demo.waitFor("Ctrl-C stops all", 90_000);
  const printed = demo.output;
  const url = /HMI at (https:\/\/\S+)/.exec(printed)?.[1];
  const password = /with password '([^']+)'/.exec(printed)?.[1];
  const fingerprint = /SHA-256 fingerprint\s+([0-9A-F:]{95})/.exec(printed)?.[1];
  expect(url, printed).toBe(`https://${httpHost}:${port}/`);
  expect(password, printed).toBeTruthy();
  expect(fingerprint, printed).toBeTruthy();
  // The address is bound before the password is printed; it listens once the service runs.
  await expect
    .poll(async () => (await page.request.get(`${url}readyz`).catch(() => null))?.status() ?? 0, { timeout: 60_000, message: "demo connected" })
    .toBe(200);
  // What the demo printed is what it serves.
  expect(await servedFingerprint(httpHost, port)).toBe(fingerprint);
  const answer = await page.goto(url!);
  expect(answer?.status()).toBe(200);
  expect(answer?.headers()["strict-transport-security"]).toBe("max-age=31536000");
  expect(page.url()).toMatch(/^https:/);

  const streams: string[] = [];
  page.on("websocket", (socket) => streams.push(socket.url()));
  await page.getByTestId("login-username").fill("operator");
  await page.getByTestId("login-password").fill(password!);
  await page.getByTestId("login-submit").click();
  await expect(page.getByTestId("current-user")).toContainText("operator");
  // Live data over WSS: the connection lamp and a robot state from the emulator.
  await expect(page.getByTestId("connection-status")).toHaveAttribute("data-state", "connected");
  await expect(page.getByTestId("robot-state")).toHaveAttribute("data-state-name", /.+/);
  expect(streams.length).toBeGreaterThan(0);
  expect(streams.every((s) => s.startsWith("wss://")), streams.join(", ")).toBe(true);

  const cookies = await page.context().cookies(url!);
  const session = cookies.find((c) => c.httpOnly);
  expect(session, JSON.stringify(cookies)).toBeTruthy();
  expect(session!.secure).toBe(true);
  expect(session!.sameSite).toBe("Strict");
});
