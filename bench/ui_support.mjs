// What the browser benchmarks share (bench/ui, bench/ui_latency): the repository's root,
// Playwright's Chromium driver from the frontend's dependencies, Debian's Chromium and its
// arguments, the checked command line, free ports, the load average printed with every figure.
import { execFileSync } from "node:child_process";
import { createRequire } from "node:module";
import net from "node:net";
import { loadavg } from "node:os";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { parseArgs } from "node:util";

export const root = resolve(dirname(fileURLToPath(import.meta.url)), "..");
export const { chromium } = createRequire(join(root, "frontend", "package.json"))("playwright-core");
export const CHROMIUM = "/usr/bin/chromium";
export const CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update", "--no-first-run"];

/**
 * The command line, checked (node:util parseArgs, strict): `numbers` are the numeric options and
 * their defaults, `paths` the options that name a file or directory. `--help` prints `usage` (the
 * wrapper script's header) and exits; an unknown option or a value that is no number is refused
 * with the usage, before any browser or service starts.
 */
export function commandLine(usage, numbers, paths = []) {
  const options = { help: { type: "boolean" } };
  for (const name of [...Object.keys(numbers), ...paths]) options[name] = { type: "string" };
  let values;
  try {
    ({ values } = parseArgs({ options, strict: true, allowPositionals: false }));
  } catch (error) {
    process.stderr.write(`${error.message}\n\n${usage}\n`);
    process.exit(2);
  }
  if (values.help) {
    process.stdout.write(`${usage}\n`);
    process.exit(0);
  }
  const out = {};
  for (const [name, fallback] of Object.entries(numbers)) {
    const text = values[name];
    if (text === undefined) {
      out[name] = fallback;
      continue;
    }
    const value = Number(text);
    if (text.trim() === "" || !Number.isFinite(value) || value < 0) {
      process.stderr.write(`--${name} ${text}: a number of at least 0, please\n\n${usage}\n`);
      process.exit(2);
    }
    out[name] = value;
  }
  for (const name of paths) out[name] = values[name];
  return out;
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

/**
 * Bytes the service at `host:port` has sent on each of its established TCP connections (Linux
 * `ss -ti`: bytes_acked, what the peer acknowledged), by the peer's address: what a page
 * received on the wire, compression and framing included, whatever the browser reports.
 */
export function tcpBytesSent(host, port) {
  const out = execFileSync("ss", ["-tinH", "state", "established", "src", `${host}:${port}`], { encoding: "utf8" });
  const sent = new Map();
  let peer = null;
  for (const line of out.split("\n")) {
    const fields = line.trim().split(/\s+/);
    // A connection's line: Recv-Q Send-Q Local Peer (the state is not printed with a filter).
    if (fields.length >= 4 && /^\d+$/.test(fields[0] ?? "") && /:\d+$/.test(fields[3] ?? "")) {
      peer = fields[3];
      continue;
    }
    const acked = /bytes_acked:(\d+)/.exec(line);
    if (acked !== null && peer !== null) sent.set(peer, Number(acked[1]));
  }
  return sent;
}

/** Bytes sent between two `tcpBytesSent` readings, on the connections of the second. */
export function bytesBetween(before, after) {
  let total = 0;
  for (const [peer, bytes] of after) total += bytes - (before.get(peer) ?? 0);
  return total;
}
