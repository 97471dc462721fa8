import { describe, expect, it } from "vitest";
import type { Frame } from "../../generated/layout";
import { completeFrame, LiveData } from "./liveData";
import { HEADER_FIELDS, PHONE_RATE_HZ, panelSubscription } from "./phoneStream";
import { JOINT_PLOTS } from "../plots/plots";
import type { ConnectionStatus, ServerMessage } from "../api/protocol";
import { StreamClient, subscribeMessage, type SocketLike } from "./stream";

class Socket implements SocketLike {
  onopen: ((ev: unknown) => void) | null = null;
  onmessage: ((ev: { data: unknown }) => void) | null = null;
  onclose: ((ev: { code?: number; reason?: string }) => void) | null = null;
  onerror: ((ev: unknown) => void) | null = null;
  readonly sent: string[] = [];
  close(): void {
    this.onclose?.({ code: 1006 });
  }
  send(data: string): void {
    this.sent.push(data);
  }
}

describe("panelSubscription", () => {
  it("asks a wide screen's stream for everything", () => {
    expect(panelSubscription(false, new Set(["joints", "io"]), true)).toBeNull();
  });

  it("asks a phone's for the header's fields and the sections' in view, at the phone's rate", () => {
    const top = panelSubscription(true, new Set(["alarms"]), false);
    expect(top?.rate_hz).toBe(PHONE_RATE_HZ);
    expect(top?.fields).toEqual([...HEADER_FIELDS].sort());
    const joints = panelSubscription(true, new Set(["alarms", "joints"]), false);
    expect(joints?.fields).toContain("joint_motor_temperature");
    expect(joints?.fields).toContain("tcp_position");
    expect(joints?.fields).not.toContain("controlbox_di");
    // The TCP plots' own fields only once the plots are opened.
    expect(panelSubscription(true, new Set(["tcp"]), false)?.fields).not.toContain("tcp_velocity");
    expect(panelSubscription(true, new Set(["tcp"]), true)?.fields).toContain("tcp_velocity");
    const io = panelSubscription(true, new Set(["io", "registers"]), false);
    expect(io?.fields).toEqual(expect.arrayContaining(["controlbox_do", "tool_di", "bit_output_registers", "robot_state"]));
    expect(new Set(io?.fields).size).toBe(io?.fields?.length);
  });
});

describe("StreamClient.subscribe", () => {
  it("sends the subscription when the socket opens, again on a new socket, and a return to everything", () => {
    const sockets: Socket[] = [];
    const client = new StreamClient(() => "ws://x/", { onMessage: () => undefined, onSocketState: () => undefined }, {
      socketFactory: () => {
        const s = new Socket();
        sockets.push(s);
        return s;
      },
      backoff: { initial_ms: 1, max_ms: 1, factor: 1, jitter: 0 },
    });
    const phone = { fields: ["robot_state"], rate_hz: 10 };
    client.subscribe(phone); // before any socket: kept
    client.start();
    const first = sockets[0];
    if (first === undefined) throw new Error("no socket");
    expect(first.sent).toEqual([]);
    first.onopen?.({});
    expect(first.sent).toEqual([subscribeMessage(phone)]);
    client.subscribe({ fields: ["robot_state"], rate_hz: 10 }); // the same again: nothing sent
    expect(first.sent).toHaveLength(1);
    client.subscribe(null);
    expect(JSON.parse(first.sent[1] ?? "")).toEqual({ type: "subscribe", fields: null, rate_hz: null });
    client.subscribe(phone);
    client.restart();
    const second = sockets[1];
    second?.onopen?.({});
    expect(second?.sent).toEqual([subscribeMessage(phone)]);
    client.stop();
  });

  it("sends nothing to a socket when the page never subscribed", () => {
    const socket = new Socket();
    const client = new StreamClient(() => "ws://x/", { onMessage: () => undefined, onSocketState: () => undefined }, { socketFactory: () => socket });
    client.start();
    socket.onopen?.({});
    client.subscribe(null);
    expect(socket.sent).toEqual([]);
    client.stop();
  });
});

describe("LiveData with a subscription", () => {
  const connection = { state: "connected", reason: null, stale: false, rpi_ms: 10 } as unknown as ConnectionStatus;

  it("shows a field not asked for as unknown, not as its last value, and counts no gaps at the asked rate", () => {
    const live = new LiveData(JOINT_PLOTS, { capacity: 64, now: () => 0 });
    live.handle({ type: "hello", robot: "r", layout_version: 1, connection, control: { holder: null }, rate_hz: null } as ServerMessage);
    const full = { robot_state: 1, joint_position: [1, 2, 3, 4, 5, 6], controlbox_di: new Array<boolean>(16).fill(true) } as unknown as Frame;
    live.handle({ type: "frames", frames: [{ seq: 1, t: 1, frame: full }] } as ServerMessage);
    live.handle({ type: "subscribed", fields: ["robot_state"], rate_hz: 10 } as ServerMessage);
    live.handle({ type: "frames", frames: [{ seq: 11, t: 1.1, frame: { robot_state: 2 } as unknown as Frame }] } as ServerMessage);
    live.publish();
    const snap = live.getSnapshot();
    expect(snap.rate_hz).toBe(10);
    expect(snap.fields).toEqual(["robot_state"]);
    expect(snap.frame?.robot_state).toBe(2);
    expect(snap.frame?.controlbox_di).toEqual(new Array(16).fill(null));
    expect(snap.frame?.joint_position).toEqual(new Array(6).fill(null));
    expect(snap.clientGaps).toBe(0);
  });

  it("leaves a whole frame as it came", () => {
    const frame = { robot_state: 3 } as unknown as Frame;
    expect(completeFrame(frame, null)).toBe(frame);
  });
});
