// What the browser benchmarks share (bench/ui, bench/ui_latency): the repository's root,
// Playwright's Chromium driver from the frontend's dependencies, Debian's Chromium and its
// arguments, command-line numbers, free ports, the load average printed with every figure.
import { createRequire } from "node:module";
import net from "node:net";
import { loadavg } from "node:os";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";

export const root = resolve(dirname(fileURLToPath(import.meta.url)), "..");
export const { chromium } = createRequire(join(root, "frontend", "package.json"))("playwright-core");
export const CHROMIUM = "/usr/bin/chromium";
export const CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update", "--no-first-run"];

/** `--name N` from the command line as a number, else `fallback`. */
export function option(name, fallback) {
  const i = process.argv.indexOf(`--${name}`);
  return i >= 0 && process.argv[i + 1] !== undefined ? Number(process.argv[i + 1]) : fallback;
}

/** The load average now, printed with every figure: the machine may be shared. */
export const load = () => loadavg().map((l) => l.toFixed(2)).join(" ");

export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/** A TCP port free on `host` right now. */
export function freePort(host) {
  return new Promise((resolvePort, reject) => {
    const server = net.createServer();
    server.once("error", reject);
    server.listen(0, host, () => {
      const { port } = server.address();
      server.close(() => resolvePort(port));
    });
  });
}

/**
 * Two loopback addresses of this process's own, 127.<a>.<b>.1 and .2: <a> from the process id
 * keeps concurrent runs apart (as the tests do), `block` (a bench's own) keeps benches apart.
 */
export function loopbackPair(block) {
  const a = (process.pid % 200) + 20;
  const b = block + (process.pid % 50);
  return { serviceHost: `127.${a}.${b}.1`, robotHost: `127.${a}.${b}.2` };
}
