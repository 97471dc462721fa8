// An independent class 1 scanner from the npm registry (st-ethernet-ip's IO.Scanner) against
// our emulator. Usage: node st_scanner.js ROBOT_HOST LOCAL_HOST SECONDS RPI_MS O2T_HEX
// Prints one JSON line per event and a summary; exits by itself after SECONDS.
"use strict";
const { IO } = require("st-ethernet-ip");

const [robotHost, localHost, secondsText, rpiText, o2tHex] = process.argv.slice(2);
const seconds = Number(secondsText);
const rpiMs = Number(rpiText);
const output = Buffer.from(o2tHex, "hex");

const scanner = new IO.Scanner(2222, localHost);
const config = {
  configInstance: { assembly: 151, size: 0 },
  outputInstance: { assembly: 150, size: output.length },
  inputInstance: { assembly: 100, size: 284 },
};
const conn = scanner.addConnection(config, rpiMs, robotHost);
const started = Date.now();
let connectedAt = null;
let disconnects = 0;

function emit(event) {
  process.stdout.write(JSON.stringify({ t_ms: Date.now() - started, ...event }) + "\n");
}

conn.on("connected", () => {
  connectedAt = Date.now();
  conn.outputData = Buffer.from(output);
  emit({ event: "connected" });
});
conn.on("disconnected", () => {
  disconnects += 1;
  emit({ event: "disconnected" });
});

setTimeout(() => {
  emit({
    event: "summary",
    connected: conn.connected === true,
    connected_ms: connectedAt === null ? 0 : Date.now() - connectedAt,
    disconnects,
    input_hex: conn.inputData.toString("hex"),
    o2t_sequence: conn.OTsequenceNum,
  });
  process.exit(0);
}, seconds * 1000);
