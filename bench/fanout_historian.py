"""The OPC UA client of ``bench/fanout --every-door`` (issue 40): a historian on every variable.

Its own process (a historian is its own machine; as a thread of the bench it shared the GIL
with the 32 WebSocket clients, and its session's health probe went unanswered on a busy
machine). It subscribes the way a plant historian does, not the way a live screen does:

- one subscription, publishing every ``--interval-ms`` (1 s), each variable sampled at the same
  interval with a queue of one (the newest value per interval; a historian records a value per
  scan, it does not replay every tick of the server);
- a keep-alive every 10 publishing intervals and a lifetime of 3 keep-alives (the spec's
  minimum ratio): a server that stops publishing is noticed within ~30 s, not an hour;
- a session timeout of 2 minutes (asyncua's default asks for an hour), requests answered
  within 60 s, and the session's health probe (a Read of the server state) every 30 s,
  answered within 30 s (asyncua's default, 1 s, gives a session up at the first slow answer of
  a loaded machine);
- the monitored items created ``BATCH`` per CreateMonitoredItems request (a server's usual
  MaxMonitoredItemsPerCall), browsing 100 nodes per Browse (bench/opcua_bench.py's ``variables``).

It prints ``ready N`` (N: the variables subscribed) on stdout once subscribed, and, when its
standard input closes, one JSON line of what it saw: notifications (after ``ready``), the
status changes the server sent (a subscription timed out, the server shutting down), lost
connections, the publish responses' sequence numbers that were missing, and each
notification's latency (the value's SourceTimestamp, the frame's receive time in the service,
to its arrival here: both clocks are this machine's) p50/p99.

Run by ``fanout_doors``: ``python fanout_historian.py ENDPOINT r1,r2,...``.
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import orjson
from asyncua import Client, ua
from opcua_bench import variables  # the same browse as bench/opcua (BROWSE_BATCH a request)

BATCH = 1000
KEEPALIVE_COUNT = 10
LIFETIME_COUNT = 3 * KEEPALIVE_COUNT
SESSION_TIMEOUT_MS = 120_000
REQUEST_TIMEOUT_S = 60.0
WATCHDOG_S = 30.0


@dataclass
class Seen:
    """What the client saw (its event loop's thread)."""

    recording: bool = False
    notifications: int = 0
    initial: int = 0
    status_changes: list[str] = field(default_factory=list)
    connections_lost: int = 0
    sequence_gaps: int = 0
    last_sequence: int | None = None
    latencies_s: list[float] = field(default_factory=list)

    def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
        received = time.time()
        if not self.recording:
            self.initial += 1
            return
        self.notifications += 1
        source = data.monitored_item.Value.SourceTimestamp
        if source is not None and len(self.latencies_s) < 1_000_000:
            self.latencies_s.append(received - source.timestamp())

    def status_change_notification(self, status: Any) -> None:
        self.status_changes.append(str(status.Status))

    def publish_sequence(self, sequence: int) -> None:
        if self.last_sequence is not None and sequence > self.last_sequence + 1:
            self.sequence_gaps += sequence - self.last_sequence - 1
        self.last_sequence = max(sequence, self.last_sequence or 0)

    def summary(self, variables: int) -> dict[str, object]:
        ordered = sorted(self.latencies_s)

        def at(q: float) -> float | None:
            return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else None

        return {
            "variables": variables,
            "initial": self.initial,
            "notifications": self.notifications,
            "status_changes": self.status_changes,
            "connections_lost": self.connections_lost,
            "sequence_gaps": self.sequence_gaps,
            "latency_p50_s": at(0.5),
            "latency_p99_s": at(0.99),
        }


async def subscribe(client: Client, nodes: list[Any], seen: Seen, interval_ms: float) -> None:
    """One subscription, its items created ``BATCH`` a request (sampling = publishing, queue 1)."""
    parameters = ua.CreateSubscriptionParameters(
        RequestedPublishingInterval=interval_ms,
        RequestedLifetimeCount=LIFETIME_COUNT,
        RequestedMaxKeepAliveCount=KEEPALIVE_COUNT,
        MaxNotificationsPerPublish=0,
        PublishingEnabled=True,
        Priority=0,
    )
    subscription = await client.create_subscription(parameters, seen)
    callbacks = client.uaclient._subscription_callbacks  # the session's, by subscription id
    original = callbacks[subscription.subscription_id]

    async def counted(response: ua.PublishResult) -> None:
        if response.NotificationMessage.NotificationData:  # a keep-alive repeats a number
            seen.publish_sequence(response.NotificationMessage.SequenceNumber)
        await original(response)

    callbacks[subscription.subscription_id] = counted
    for start in range(0, len(nodes), BATCH):
        await subscription.subscribe_data_change(
            nodes[start : start + BATCH], sampling_interval=interval_ms, queuesize=1
        )


async def run(endpoint: str, names: list[str], interval_ms: float) -> None:
    # A lost session is counted and printed at the end; asyncua's publish loop would log a
    # traceback a second until then.
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)
    seen = Seen()
    client = Client(endpoint, timeout=REQUEST_TIMEOUT_S, watchdog_intervall=WATCHDOG_S)
    client.session_timeout = SESSION_TIMEOUT_MS

    async def lost(error: Exception) -> None:
        seen.connections_lost += 1

    client.connection_lost_callback = lost
    await client.connect()
    nodes = await variables(client, names)
    await subscribe(client, nodes, seen, interval_ms)
    loop = asyncio.get_running_loop()
    await asyncio.sleep(2 * interval_ms / 1000)  # the initial values in, before counting
    seen.recording = True
    print(f"ready {len(nodes)}", flush=True)
    closed = asyncio.Event()
    threading.Thread(
        target=lambda: (sys.stdin.read(), loop.call_soon_threadsafe(closed.set)), daemon=True
    ).start()
    await closed.wait()
    seen.recording = False
    summary = seen.summary(len(nodes))
    try:
        await asyncio.wait_for(client.disconnect(), 20)
    except Exception as error:  # the figures still count; say why the goodbye failed
        summary["disconnect_error"] = repr(error)
    print(orjson.dumps(summary).decode(), flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("endpoint")
    parser.add_argument("robots", help="comma-separated robot names")
    parser.add_argument("--interval-ms", type=float, default=1000.0)
    args = parser.parse_args()
    asyncio.run(run(args.endpoint, args.robots.split(","), args.interval_ms))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
