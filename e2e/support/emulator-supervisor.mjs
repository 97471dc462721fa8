// The emulator as a process the tests control (started by Playwright's webServer).
//
//   node emulator-supervisor.mjs PIDFILE -- COMMAND [ARGS...]
//
// Runs COMMAND (`cobot-hmi emulator ...`) and writes {"supervisor": pid, "emulator": pid} to
// PIDFILE. When the emulator dies (a test kills it with SIGKILL), it stays down until the
// supervisor receives SIGUSR1, which starts it again and rewrites PIDFILE. SIGTERM or SIGINT
// (Playwright's shutdown, sent to the whole process group) stops the emulator and then this
// process; an emulator that does not stop within 5 s is killed.
import { spawn } from "node:child_process";
import { renameSync, writeFileSync } from "node:fs";

const [pidFile, separator, command, ...args] = process.argv.slice(2);
if (!pidFile || separator !== "--" || !command) {
  console.error("usage: emulator-supervisor.mjs PIDFILE -- COMMAND [ARGS...]");
  process.exit(2);
}

let child = null;
let stopping = false;

function writePids() {
  const temporary = `${pidFile}.tmp`;
  writeFileSync(temporary, JSON.stringify({ supervisor: process.pid, emulator: child?.pid ?? null }));
  renameSync(temporary, pidFile); // readers never see a half-written file
}

function start() {
  const started = spawn(command, args, { stdio: "inherit" });
  child = started;
  started.on("exit", (code, signal) => {
    if (child === started) child = null;
    writePids();
    if (stopping) process.exit(0);
    console.error(`[emulator-supervisor] emulator ${started.pid} exited (${signal ?? code}); SIGUSR1 restarts it`);
  });
  started.on("error", (error) => {
    console.error(`[emulator-supervisor] cannot run ${command}: ${error.message}`);
    process.exit(1);
  });
  writePids();
}

process.on("SIGUSR1", () => {
  if (child === null && !stopping) // Signal handlers do not keep Node alive: while the emulator is down, this timer does.
setInterval(() => {}, 1 << 30);
start();
});

function stop() {
  if (stopping) return;
  stopping = true;
  if (child === null) process.exit(0);
  child.kill("SIGTERM");
  setTimeout(() => {
    child?.kill("SIGKILL");
    process.exit(0);
  }, 5000).unref();
}
process.on("SIGTERM", stop);
process.on("SIGINT", stop);

// Signal handlers do not keep Node alive: while the emulator is down, this timer does.
setInterval(() => {}, 1 << 30);
start();
