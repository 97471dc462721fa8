import { describe, expect, it } from "vitest";
import { connectionHealth, formatDuration_ms, packetLossOf } from "./health";
import type { ConnectionStatus } from "../api/protocol";

const connected: ConnectionStatus = {
  state: "connected",
  reason: null,
  robot: "127.0.0.1",
  mode: "exclusive_owner",
  rpi_ms: 10,
  packets_in: 100,
  packets_out: 100,
  gaps: 0,
  duplicates: 0,
  late: 0,
  malformed: 0,
  interval_mean_ms: 10,
  interval_p99_ms: 10.4,
  interval_max_ms: 11,
  last_frame_age_s: 0.004,
  stale: false,
  connected_since: 1,
};

describe("connectionHealth", () => {
  it("is connected only with an open socket, a robot link and a fresh frame", () => {
    expect(connectionHealth({ socket: "open", connection: connected, frameAge_ms: 20 })).toBe("connected");
  });
  it("is disconnected without the socket or without the robot link", () => {
    expect(connectionHealth({ socket: "closed", connection: connected, frameAge_ms: 20 })).toBe("disconnected");
    expect(connectionHealth({ socket: "connecting", connection: connected, frameAge_ms: 20 })).toBe("disconnected");
    expect(connectionHealth({ socket: "open", connection: null, frameAge_ms: 20 })).toBe("disconnected");
    for (const state of ["lost", "refused", "idle", "connecting"] as const) {
      expect(connectionHealth({ socket: "open", connection: { ...connected, state }, frameAge_ms: 20 })).toBe(
        "disconnected",
      );
    }
  });
  it("is stale when the newest frame is too old or the backend says so", () => {
    expect(connectionHealth({ socket: "open", connection: connected, frameAge_ms: 5000 })).toBe("stale");
    expect(connectionHealth({ socket: "open", connection: connected, frameAge_ms: null })).toBe("stale");
    expect(connectionHealth({ socket: "open", connection: { ...connected, stale: true }, frameAge_ms: 5 })).toBe(
      "stale",
    );
  });
  it("formats durations for people", () => {
    expect(formatDuration_ms(12.4)).toBe("12 ms");
    expect(formatDuration_ms(3400)).toBe("3.4 s");
    expect(formatDuration_ms(null)).toBe("—");
  });
});

describe("packetLossOf", () => {
  const lossy: ConnectionStatus = { ...connected, gaps: 240, gaps_per_min: 240, packet_loss_high: true };

  it("turns a live badge amber while the service's packet-loss alarm is active, naming the rate", () => {
    expect(packetLossOf("connected", lossy)).toEqual({ high: true, words: "packet loss: 240 gaps in the last minute" });
    expect(packetLossOf("connected", { ...lossy, gaps_per_min: null }).words).toBe("packet loss: ? gaps in the last minute");
  });

  it("is normal when the service says so, whatever the gap count", () => {
    expect(packetLossOf("connected", { ...lossy, packet_loss_high: false })).toEqual({ high: false, words: null });
    expect(packetLossOf("connected", connected)).toEqual({ high: false, words: null }); // an older service: no field
  });

  it("leaves a stale or disconnected badge its own colour", () => {
    expect(packetLossOf("stale", lossy).high).toBe(false);
    expect(packetLossOf("disconnected", lossy).high).toBe(false);
    expect(packetLossOf("connected", null).high).toBe(false);
  });
});
