"""Benchmark of issue 22 (``bench/opcua``): the service as an OPC UA server.

Four emulated robots (``--robots``) at RPI 10 ms, each its own process, and the service holding
a class 1 connection to each. Two conditions in the same run, alternating ``--cycles`` times
(the machine's other load drifts; both must see it): the service started without
``--opcua-url`` (off) and with it (on), ``--seconds`` of each in all, the service restarted for
each phase and measured after ``--settle-seconds``. With ``--baseline COMMIT`` a third
condition alternates with them: that commit's service with its OPC UA server on (checked out in
a git worktree, ``--baseline-worktree``), so a change to the server is measured against its
predecessor at the same load. In the "on" phases one client (asyncua, on a thread of this
process) is subscribed to every variable of every robot (the whole DeviceSet below the robots'
objects) at 100 ms sampling and publishing.

With ``--historian`` the client subscribes as ``bench/fanout --every-door``'s historian does
(``fanout_historian``: sampling and publishing every 1000 ms, a queue of one per item) instead.

Printed: notifications/s received; latency frame → client, p50/p99 (each notification's
SourceTimestamp, the frame's kernel receive time in the service, to its arrival here: both
clocks are this machine's); the service's CPU % of a core on and off and their difference per
robot (the server's cost), and that cost per notification received and per robot-frame (the
robots' frames in the phase, one an RPI each); per robot the cyclic receive interval p99 (the
``frame_receive_interval_seconds`` histogram between two scrapes) on and off, and their ratio;
each for the baseline too when there is one. Targets: p99 ≤ 150 ms, ≤ 5 % of a core per robot,
ratio ≤ 1.1.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from asyncua import Client, ua
from fanout_sweep import ROOT, baseline_source
from proc_stats import own_cpu_s, process_cpu_s
from service_bench_support import (
    Cell,
    _wait,
    emulated_cell,
    free_port,
    histogram_quantile,
    stop_process,
)
from sparkplug_bench import HISTOGRAM, _ready, _scrape, percentile

SAMPLING_MS = 100.0
HISTORIAN_MS = 1000.0
"""``--historian``: the sampling and publishing interval of bench/fanout's historian."""
BROWSE_BATCH = 100
WATCHDOG_S = 10.0
"""The client's health probe: a Read of the server state every this often, answered within it
(asyncua's default, 1 s, tears the session down when a loaded machine delays one answer: the
notifications would stop unseen for the rest of the phase; losses are counted and printed)."""


@dataclass
class Received:
    """What the client saw (its own thread)."""

    latencies_s: list[float] = field(default_factory=list)
    notifications: int = 0
    connections_lost: int = 0
    recording: bool = False
    lock: threading.Lock = field(default_factory=threading.Lock)

    def datachange_notification(self, node: Any, value: Any, data: Any) -> None:
        received = time.time()
        if not self.recording:
            return
        source = data.monitored_item.Value.SourceTimestamp
        with self.lock:
            self.notifications += 1
            if source is not None:
                self.latencies_s.append(received - source.timestamp())


async def variables(client: Client, names: list[str]) -> list[Any]:
    """Every variable below each robot's object (its Robotics parts and its layout), browsed
    ``BROWSE_BATCH`` nodes per request."""
    found: list[Any] = []
    namespaces = await client.get_namespace_array()
    level = [ua.NodeId(name, namespaces.index(f"urn:cobot-hmi:robot:{name}")) for name in names]
    seen = set(level)
    while level:
        batch, level = level[:BROWSE_BATCH], level[BROWSE_BATCH:]
        parameters = ua.BrowseParameters()
        for node_id in batch:
            description = ua.BrowseDescription()
            description.NodeId = node_id
            description.BrowseDirection = ua.BrowseDirection.Forward
            description.ReferenceTypeId = ua.NodeId(ua.ObjectIds.HierarchicalReferences)
            description.IncludeSubtypes = True
            description.NodeClassMask = 0
            description.ResultMask = ua.BrowseResultMask.All
            parameters.NodesToBrowse.append(description)
        results = await client.uaclient.browse(parameters)
        for result in results:
            for reference in result.References:
                node_id = reference.NodeId
                if node_id in seen:
                    continue
                seen.add(node_id)
                if reference.NodeClass == ua.NodeClass.Variable:
                    found.append(client.get_node(node_id))
                if reference.NodeClass in (ua.NodeClass.Object, ua.NodeClass.Variable):
                    level.append(node_id)
    return found


class Subscriber:
    """The asyncua client on a thread and loop of its own, subscribed during an "on" phase."""

    def __init__(
        self, endpoint: str, names: list[str], received: Received, historian: bool = False
    ) -> None:
        self._interval_ms = HISTORIAN_MS if historian else SAMPLING_MS
        self._queue_size = 1 if historian else 0  # 0: asyncua's default (the server's largest)
        self._endpoint = endpoint
        self._names = names
        self._received = received
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)
        self._thread.start()
        self._client: Client | None = None
        self.variables = 0

    def _run(self, coroutine: Any) -> Any:
        return asyncio.run_coroutine_threadsafe(coroutine, self._loop).result(300)

    def start(self) -> None:
        self._run(self._start())

    async def _lost(self, error: Exception) -> None:
        self._received.connections_lost += 1

    async def _start(self) -> None:
        client = Client(self._endpoint, timeout=120, watchdog_intervall=WATCHDOG_S)
        client.connection_lost_callback = self._lost
        await client.connect()
        self._client = client
        nodes = await variables(client, self._names)
        self.variables = len(nodes)
        interval_ms = self._interval_ms
        subscription = await client.create_subscription(interval_ms, self._received)
        for start in range(0, len(nodes), 500):
            await subscription.subscribe_data_change(
                nodes[start : start + 500],
                sampling_interval=interval_ms,
                queuesize=self._queue_size,
            )

    def stop(self) -> None:
        if self._client is not None:
            self._run(self._client.disconnect())
            self._client = None

    def close(self) -> None:
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10)


@dataclass(frozen=True)
class Condition:
    """What one phase runs: the service with or without OPC UA, this checkout's or another's."""

    label: str
    on: bool
    source: Path | None = None
    """Another commit's ``backend/src`` (the baseline); ``None``: this checkout's."""
    received: Received = field(default_factory=Received)


@dataclass
class Phase:
    condition: Condition
    seconds: float
    service_cpu_s: float
    bench_cpu_s: float
    p99_s: dict[str, float]
    intervals: dict[str, int]
    variables: int = 0


def run_phase(
    args: argparse.Namespace,
    condition: Condition,
    cell: Cell,
) -> Phase:
    on, received, names = condition.on, condition.received, cell.names
    endpoint = f"opc.tcp://{cell.service_host}:{free_port(cell.service_host)}"
    extra = ["--opcua-url", endpoint] if on else []
    service, http_port = cell.serve(
        args.rpi_ms,
        "--no-history",
        *extra,
        log=f"service-{condition.label}.log",
        source=condition.source,
    )
    base_url = f"http://{cell.service_host}:{http_port}"
    subscriber = Subscriber(endpoint, names, received, args.historian) if on else None
    try:
        _wait(lambda: _ready(base_url, names), "service", service, 120)
        if subscriber is not None:
            subscriber.start()
        time.sleep(args.settle_seconds)
        seconds = args.seconds / args.cycles
        before = _scrape(base_url)
        cpu0 = (process_cpu_s(service.pid), own_cpu_s())
        received.recording = on
        started = time.monotonic()
        time.sleep(seconds)
        elapsed = time.monotonic() - started
        received.recording = False
        cpu1 = (process_cpu_s(service.pid), own_cpu_s())
        after = _scrape(base_url)
    finally:
        if subscriber is not None:
            subscriber.stop()
            subscriber.close()
        stop_process(service, 20)
    p99: dict[str, float] = {}
    counts: dict[str, int] = {}
    for name in names:
        p99[name], counts[name] = histogram_quantile(before, after, HISTOGRAM, 0.99, robot=name)
    return Phase(
        condition,
        elapsed,
        cpu1[0] - cpu0[0],
        cpu1[1] - cpu0[1],
        p99,
        counts,
        subscriber.variables if subscriber is not None else 0,
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=4)
    parser.add_argument("--rpi-ms", type=float, default=10.0)
    parser.add_argument("--seconds", type=float, default=60.0, help="of each condition, in all")
    parser.add_argument("--cycles", type=int, default=3, help="off/on alternations")
    parser.add_argument("--settle-seconds", type=float, default=3.0)
    parser.add_argument(
        "--historian",
        action="store_true",
        help=f"subscribe as bench/fanout's historian: every {HISTORIAN_MS:g} ms, queue 1",
    )
    parser.add_argument(
        "--robot-niceness",
        type=int,
        default=-10,
        help="nice value of the emulators (a real robot is its own machine; 0: same as the rest)",
    )
    parser.add_argument(
        "--baseline",
        default="",
        help="also run this commit's service with OPC UA on, alternating with the others",
    )
    parser.add_argument(
        "--baseline-worktree",
        type=Path,
        default=None,
        help="where the baseline is checked out (default: beside the repository; made if missing)",
    )
    args = parser.parse_args()
    conditions = [Condition("off", False), Condition("on", True)]
    if args.baseline:
        worktree = args.baseline_worktree or ROOT.parent / f"cobot-hmi-bench-{args.baseline}"
        source = baseline_source(args.baseline, worktree)
        conditions.insert(1, Condition(f"baseline {args.baseline}", True, source))
    phases: list[Phase] = []
    with (
        tempfile.TemporaryDirectory(prefix="cobot-bench-opcua-") as directory,
        emulated_cell(args.robots, Path(directory), robot_niceness=args.robot_niceness) as cell,
    ):
        for _ in range(args.cycles):
            for condition in conditions:
                phases.append(run_phase(args, condition, cell))
    report(args, cell.names, conditions, phases)
    return 0


def report(
    args: argparse.Namespace,
    names: list[str],
    conditions: list[Condition],
    phases: list[Phase],
) -> None:
    def of(condition: Condition) -> list[Phase]:
        return [p for p in phases if p.condition is condition]

    def cpu_percent(condition: Condition) -> float:
        chosen = of(condition)
        return sum(p.service_cpu_s for p in chosen) / sum(p.seconds for p in chosen) * 100

    off = conditions[0]
    service_off = cpu_percent(off)
    print(
        f"bench/opcua: {args.robots} robots at RPI {args.rpi_ms:g} ms; {args.cycles} "
        f"alternations of {args.seconds / args.cycles:g} s of each condition "
        f"({', '.join(c.label for c in conditions)}; OPC UA monitoring 10 Hz), one client "
        f"subscribed to every variable "
        f"({max(p.variables for p in phases)}) "
        f"at {HISTORIAN_MS if args.historian else SAMPLING_MS:g} ms"
        f"{', queue 1' if args.historian else ''}; emulators at nice {args.robot_niceness}; "
        f"{os.cpu_count()} CPUs, "
        "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg())
    )
    print(f"  service CPU without OPC UA: {service_off:.1f} % of a core")
    for condition in conditions[1:]:
        on = of(condition)
        on_s = sum(p.seconds for p in on)
        received = condition.received
        server = cpu_percent(condition) - service_off
        bench = sum(p.bench_cpu_s for p in on) / on_s * 100
        print(f"  {condition.label}:")
        print(
            f"    notifications received: {received.notifications / on_s:.0f}/s; the client's "
            f"connection lost {received.connections_lost} times"
        )
        print(
            f"    latency frame → client ({len(received.latencies_s)} notifications): p50 "
            f"{percentile(received.latencies_s, 0.5) * 1e3:.1f} ms, p99 "
            f"{percentile(received.latencies_s, 0.99) * 1e3:.1f} ms (target ≤ 150 ms)"
        )
        print(
            f"    service CPU {cpu_percent(condition):.1f} % of a core: the server "
            f"{server:.1f} % ({server / args.robots:.1f} % per robot, target ≤ 5 %); "
            f"the client (this process): {bench:.1f} %"
        )
        server_s = server / 100 * on_s
        robot_frames = args.robots * on_s * 1000 / args.rpi_ms
        print(
            f"    the server's CPU per notification received "
            f"{server_s / max(1, received.notifications) * 1e6:.1f} µs, per robot-frame "
            f"{server_s / robot_frames * 1e6:.1f} µs"
        )
        for name in names:
            p99_on = max(p.p99_s[name] for p in on)
            p99_off = max(p.p99_s[name] for p in of(off))
            ratio = p99_on / p99_off if p99_off else float("nan")
            frames = sum(p.intervals[name] for p in on)
            print(
                f"    {name}: cyclic receive interval p99 {p99_on * 1e3:.2f} ms on, "
                f"{p99_off * 1e3:.2f} ms off: ratio {ratio:.3f} (target ≤ 1.1; "
                f"{frames} intervals on)"
            )


if __name__ == "__main__":
    raise SystemExit(main())
