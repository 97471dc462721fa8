import { afterEach, beforeEach, describe, expect, it, vi } from "vitest";
import type { SocketState } from "./health";
import type { ServerMessage } from "../api/protocol";
import { StreamClient, closeReason, streamUrl, type SocketLike } from "./stream";

class FakeSocket implements SocketLike {
  onopen: ((ev: unknown) => void) | null = null;
  onmessage: ((ev: { data: unknown }) => void) | null = null;
  onclose: ((ev: { code?: number; reason?: string }) => void) | null = null;
  onerror: ((ev: unknown) => void) | null = null;
  closed = false;
  constructor(readonly url: string) {}
  close(): void {
    this.closed = true;
  }
  open(): void {
    this.onopen?.({});
  }
  send(message: object | string): void {
    this.onmessage?.({ data: typeof message === "string" ? message : JSON.stringify(message) });
  }
  drop(code = 1006, reason = ""): void {
    this.onclose?.({ code, reason });
  }
}

const hello = {
  type: "hello",
  layout_version: 1,
  connection: { state: "connected" },
  control: { holder: null },
  rate_hz: null,
};

function setup(random = () => 0) {
  const sockets: FakeSocket[] = [];
  const states: SocketState[] = [];
  const messages: ServerMessage[] = [];
  const reasons: (string | null)[] = [];
  const client = new StreamClient(
    () => "ws://h/api/v1/stream",
    { onMessage: (m) => messages.push(m), onSocketState: (s) => states.push(s), onCloseReason: (r) => reasons.push(r) },
    {
      backoff: { initial_ms: 100, max_ms: 1000, factor: 2, jitter: 0.5 },
      random,
      silenceTimeout_ms: 3000,
      socketFactory: (url) => {
        const s = new FakeSocket(url);
        sockets.push(s);
        return s;
      },
    },
  );
  return { client, sockets, states, messages, reasons };
}

describe("StreamClient", () => {
  beforeEach(() => {
    vi.useFakeTimers();
  });
  afterEach(() => {
    vi.useRealTimers();
  });

  it("builds the stream URL of the page's origin", () => {
    expect(streamUrl({ protocol: "http:", host: "h:8000" }, null)).toBe("ws://h:8000/api/v1/stream");
    expect(streamUrl({ protocol: "https:", host: "h" }, null, 20)).toBe("wss://h/api/v1/stream?rate=20");
    expect(streamUrl({ protocol: "http:", host: "h" }, null, undefined, "a b")).toBe("ws://h/api/v1/stream?token=a+b");
  });

  it("streams the named robot on its own path", () => {
    expect(streamUrl({ protocol: "http:", host: "h:8000" }, "cell-2")).toBe("ws://h:8000/api/v1/robots/cell-2/stream");
    expect(streamUrl({ protocol: "https:", host: "h" }, "m0609", 25, "t")).toBe(
      "wss://h/api/v1/robots/m0609/stream?rate=25&token=t",
    );
    // A name is one path segment whatever it holds (the service's names never need this).
    expect(streamUrl({ protocol: "http:", host: "h" }, "a/b")).toBe("ws://h/api/v1/robots/a%2Fb/stream");
  });

  it("parses messages and skips bad ones without stopping", () => {
    const { client, sockets, messages } = setup();
    client.start();
    const s = sockets[0] as FakeSocket;
    s.open();
    s.send(hello);
    s.send("{not json");
    s.send({ type: "frames", frames: "nope" });
    s.send({ type: "dropped", count: 3 });
    expect(messages.map((m) => m.type)).toEqual(["hello", "dropped"]);
    expect(client.badMessages).toBe(2);
    client.stop();
  });

  it("reconnects after a close with growing, jittered delays, and resets after a hello", () => {
    const { client, sockets, states } = setup(() => 0);
    client.start();
    (sockets[0] as FakeSocket).drop();
    expect(client.lastDelay_ms).toBe(100);
    vi.advanceTimersByTime(99);
    expect(sockets).toHaveLength(1);
    vi.advanceTimersByTime(1);
    expect(sockets).toHaveLength(2);
    (sockets[1] as FakeSocket).drop();
    expect(client.lastDelay_ms).toBe(200);
    vi.advanceTimersByTime(200);
    (sockets[2] as FakeSocket).drop();
    expect(client.lastDelay_ms).toBe(400);
    vi.advanceTimersByTime(400);
    const s3 = sockets[3] as FakeSocket;
    s3.open();
    s3.send(hello);
    s3.drop();
    expect(client.lastDelay_ms).toBe(100);
    expect(client.reconnects).toBe(3);
    expect(states).toContain("open");
    expect(states.at(-1)).toBe("closed");
    client.stop();
  });

  it("reports the service's close codes in words and keeps retrying", () => {
    const { client, sockets, reasons } = setup();
    client.start();
    (sockets[0] as FakeSocket).drop(4401, "login required");
    expect(reasons.at(-1)).toBe("the service requires a login to view: login required");
    vi.advanceTimersByTime(10_000);
    (sockets[1] as FakeSocket).open();
    expect(reasons.at(-1)).toBeNull();
    (sockets[1] as FakeSocket).drop(4400);
    expect(reasons.at(-1)).toContain("rate");
    (sockets.at(-1) as FakeSocket).drop(1006);
    client.stop();
    expect(closeReason(1000, "")).toBeNull();
    expect(closeReason(4404, "unknown robot 'x'; known: a, b")).toBe("the service has no such robot: unknown robot 'x'; known: a, b");
    // A session that ended (logout, revoked, its user changed) closes its streams with 1008.
    expect(closeReason(1008, "session ended: logged out")).toBe("the service closed the stream: session ended: logged out");
    expect(closeReason(1008, "")).toBe("the service closed the stream: its session ended");
  });

  it("applies jitter from the random source", () => {
    const { client, sockets } = setup(() => 1);
    client.start();
    (sockets[0] as FakeSocket).drop();
    expect(client.lastDelay_ms).toBe(50);
    client.stop();
  });

  it("closes a silent socket and reconnects", () => {
    const { client, sockets } = setup();
    client.start();
    const s = sockets[0] as FakeSocket;
    s.open();
    s.send(hello);
    vi.advanceTimersByTime(2999);
    expect(s.closed).toBe(false);
    vi.advanceTimersByTime(1);
    expect(s.closed).toBe(true);
    vi.advanceTimersByTime(100);
    expect(sockets).toHaveLength(2);
    // The old socket's late close is ignored (no second retry).
    s.drop();
    vi.advanceTimersByTime(10_000);
    expect(sockets).toHaveLength(2);
    client.stop();
  });

  it("stops for good: no reconnect after stop", () => {
    const { client, sockets } = setup();
    client.start();
    client.stop();
    (sockets[0] as FakeSocket).drop();
    vi.advanceTimersByTime(60_000);
    expect(sockets).toHaveLength(1);
    expect(vi.getTimerCount()).toBe(0);
  });

  it("reconnects at once, with no reason shown, when this page's own logout ends the session", () => {
    const { client, sockets, states, reasons } = setup();
    client.start();
    (sockets[0] as FakeSocket).open();
    client.expectSessionEnd();
    (sockets[0] as FakeSocket).drop(1008, "session ended: logged out");
    expect(sockets).toHaveLength(2); // at once, no back-off timer
    expect(reasons.filter((r) => r !== null)).toEqual([]);
    expect(states).not.toContain("closed");
    // Expected once: another session's end later (revoked, by an admin) is news again.
    (sockets[1] as FakeSocket).open();
    (sockets[1] as FakeSocket).drop(1008, "session ended: revoked");
    expect(reasons.at(-1)).toBe("the service closed the stream: session ended: revoked");
    expect(states.at(-1)).toBe("closed");
    expect(sockets).toHaveLength(2);
    client.stop();
  });

  it("an expected session end that never came does not hide a later one", () => {
    const { client, sockets, reasons } = setup();
    client.start();
    client.expectSessionEnd();
    client.restart(); // the logout's answer came first: the page reconnected by itself
    (sockets[1] as FakeSocket).open();
    (sockets[1] as FakeSocket).drop(1008, "session ended: revoked");
    expect(reasons.at(-1)).toBe("the service closed the stream: session ended: revoked");
    client.stop();
  });

  it("restart opens a fresh socket at once", () => {
    const { client, sockets } = setup();
    client.start();
    (sockets[0] as FakeSocket).open();
    client.restart();
    expect((sockets[0] as FakeSocket).closed).toBe(true);
    expect(sockets).toHaveLength(2);
    client.stop();
  });
});
