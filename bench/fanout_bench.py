"""Benchmark of issues 5 and 12 (``bench/fanout``): 50 WebSocket clients at full rate plus one
that never reads, against the service holding class 1 connections at RPI 10 ms to one robot, or
to several (``--robots 4``: the clients spread over the robots' streams).

The emulators (one per robot) and the service run as their own processes on fresh loopback
addresses; the clients run in this process. Two conditions in the same run, alternating
``--cycles`` times so that both see the same machine (other processes' load drifts):

1. baseline: no WebSocket client, ``--baseline-seconds`` in all;
2. load: ``--clients`` clients reading every frame, ``--seconds`` in all, plus one raw
   WebSocket to the first robot's stream that never reads (opened at the first load phase, kept
   until the end).

The cyclic interval is the receive interval of consecutive T→O frames of each robot in the
service (the ``cobot_hmi_frame_receive_interval_seconds`` histogram of that robot, 0.25 ms
buckets, taken between two scrapes of /metrics at each phase's start and end, summed per
condition); per robot its p99 under load is divided by its p99 at baseline. Printed per robot:
the p99s and their ratio, frames produced and delivered per client; then drops (frames a client
never saw, ``dropped`` notices), what happened to the never-reading client, the service's CPU
per robot-frame with and without clients, and the CPU % of the service, the emulators and this
process. Targets: fast clients lose nothing; every robot's p99 ratio stays ≤ 1.2.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import functools
import os
import socket
import statistics
import time
from dataclasses import dataclass, field
from pathlib import Path

import fanout_doors
import orjson
from proc_stats import own_cpu_s, process_cpu_s
from service_bench_support import (
    Stack,
    histogram_quantile,
    labels_of,
    metrics,
    stack,
    value_of,
)
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed

HISTOGRAM = "cobot_hmi_frame_receive_interval_seconds"


@dataclass
class ClientRecord:
    frames: int = 0
    first_seq: int | None = None
    last_seq: int | None = None
    missing: int = 0
    dropped_told: int = 0
    messages: int = 0
    frames_messages: int = 0
    connected_s: float = 0.0
    """From the handshake's end to the client's stop (or its close)."""
    closed: str | None = None
    seqs_out_of_order: int = 0
    latencies_s: list[float] = field(default_factory=list)


async def fast_client(url: str, record: ClientRecord, stop: asyncio.Event) -> None:
    connected_at: float | None = None
    try:
        async with connect(url, max_size=None) as ws:
            connected_at = time.monotonic()
            while not stop.is_set():
                try:
                    text = await asyncio.wait_for(ws.recv(), 1.0)
                except TimeoutError:
                    continue
                message = orjson.loads(text)
                record.messages += 1
                kind = message["type"]
                if kind == "dropped":
                    record.dropped_told += message["count"]
                elif kind == "frames":
                    record.frames_messages += 1
                    now = time.time()
                    for frame in message["frames"]:
                        seq = frame["seq"]
                        if record.last_seq is not None:
                            if seq <= record.last_seq:
                                record.seqs_out_of_order += 1
                            else:
                                record.missing += seq - record.last_seq - 1
                        if record.first_seq is None:
                            record.first_seq = seq
                        record.last_seq = seq
                        record.frames += 1
                    record.latencies_s.append(now - message["frames"][-1]["t"])
    except ConnectionClosed as closed:
        record.closed = f"closed by the server: {closed}"
    finally:
        if connected_at is not None:
            record.connected_s += time.monotonic() - connected_at


async def never_reading_client(host: str, port: int, path: str) -> socket.socket:
    """A raw WebSocket handshake; afterwards the socket is never read (a frozen browser tab)."""
    loop = asyncio.get_running_loop()
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.setblocking(False)
    await loop.sock_connect(sock, (host, port))
    await loop.sock_sendall(
        sock,
        (
            f"GET {path} HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
            "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
            "Sec-WebSocket-Version: 13\r\n\r\n"
        ).encode(),
    )
    head = await loop.sock_recv(sock, 200)
    if not head.startswith(b"HTTP/1.1 101"):
        raise SystemExit(f"never-reading client: handshake failed: {head!r}")
    return sock


async def socket_was_cut(sock: socket.socket) -> bool:
    loop = asyncio.get_running_loop()
    try:
        for _ in range(100_000):
            if not await asyncio.wait_for(loop.sock_recv(sock, 1 << 16), 2.0):
                return True
    except ConnectionResetError:
        return True
    except TimeoutError:
        return False
    return False


@dataclass
class RobotPhase:
    """One robot's figures in one phase."""

    p99_s: float
    p50_s: float
    intervals: int
    frames_produced: int
    originator_p99_ms: float | None
    buckets: dict[tuple[str, str], float] = field(default_factory=dict)
    """The robot's histogram bucket counts observed during the phase (after minus before)."""

    def merged(self, other: RobotPhase) -> RobotPhase:
        buckets = {k: v + other.buckets.get(k, 0.0) for k, v in self.buckets.items()}
        p99, count = histogram_quantile({}, buckets, HISTOGRAM, 0.99)
        p50, _ = histogram_quantile({}, buckets, HISTOGRAM, 0.50)
        return RobotPhase(
            p99_s=p99,
            p50_s=p50,
            intervals=count,
            frames_produced=self.frames_produced + other.frames_produced,
            originator_p99_ms=other.originator_p99_ms,
            buckets=buckets,
        )


@dataclass
class Phase:
    seconds: float
    service_cpu_s: float
    emulator_cpu_s: float
    bench_cpu_s: float
    robots: dict[str, RobotPhase]
    stalled_at_s: float | None = None

    def merged(self, other: Phase) -> Phase:
        """Two phases as one (all baselines, all loads)."""
        return Phase(
            seconds=self.seconds + other.seconds,
            service_cpu_s=self.service_cpu_s + other.service_cpu_s,
            emulator_cpu_s=self.emulator_cpu_s + other.emulator_cpu_s,
            bench_cpu_s=self.bench_cpu_s + other.bench_cpu_s,
            robots={name: r.merged(other.robots[name]) for name, r in self.robots.items()},
        )

    @property
    def frames_produced(self) -> int:
        return sum(r.frames_produced for r in self.robots.values())

    def cpu_percent(self, cpu_s: float) -> float:
        return 100 * cpu_s / self.seconds

    def service_us_per_frame(self) -> float:
        """Service CPU per robot-frame (all robots' frames), µs."""
        return 1e6 * self.service_cpu_s / max(self.frames_produced, 1)


async def measure(running: Stack, seconds: float, watch_stall: bool = False) -> Phase:
    loop = asyncio.get_running_loop()

    async def scrape() -> dict[tuple[str, str], float]:
        return metrics((await loop.run_in_executor(None, running.get, "/metrics")).decode())

    before = await scrape()
    service0 = process_cpu_s(running.service.pid)
    emulators0 = sum(process_cpu_s(e.pid) for e in running.emulators)
    bench0 = own_cpu_s()
    started = time.monotonic()
    stalled_at = None
    while (elapsed := time.monotonic() - started) < seconds:
        await asyncio.sleep(min(1.0, seconds - elapsed))
        stalled = "cobot_hmi_ws_stalled_disconnects_total"
        if watch_stall and stalled_at is None and value_of(await scrape(), stalled) >= 1:
            stalled_at = time.monotonic() - started
    wall = time.monotonic() - started
    after = await scrape()
    service_cpu_s = process_cpu_s(running.service.pid) - service0
    emulator_cpu_s = sum(process_cpu_s(e.pid) for e in running.emulators) - emulators0
    bench_cpu_s = own_cpu_s() - bench0
    robots = {}
    for name in running.robot_names:
        status = orjson.loads(
            await loop.run_in_executor(None, running.get, f"/api/v1/robots/{name}/status")
        )
        p99, count = histogram_quantile(before, after, HISTOGRAM, 0.99, robot=name)
        p50, _ = histogram_quantile(before, after, HISTOGRAM, 0.50, robot=name)
        produced = value_of(after, "cobot_hmi_hub_frames_total", name) - value_of(
            before, "cobot_hmi_hub_frames_total", name
        )
        robots[name] = RobotPhase(
            p99_s=p99,
            p50_s=p50,
            intervals=count,
            frames_produced=int(produced),
            originator_p99_ms=status["connection"]["interval_p99_ms"],
            buckets={
                key: value - before.get(key, 0.0)
                for key, value in after.items()
                if key[0] == HISTOGRAM + "_bucket" and labels_of(key[1]).get("robot") == name
            },
        )
    return Phase(wall, service_cpu_s, emulator_cpu_s, bench_cpu_s, robots, stalled_at)


def robot_of_client(running: Stack, index: int) -> str:
    """Clients spread over the robots in turn."""
    return running.robot_names[index % len(running.robot_names)]


async def load_phase(
    args: argparse.Namespace, running: Stack, watch_stall: bool
) -> tuple[Phase, list[ClientRecord]]:
    """``--clients`` fast clients streaming for one share of ``--seconds``, then closed."""
    stop = asyncio.Event()
    records = [ClientRecord() for _ in range(args.clients)]
    tasks = [
        asyncio.create_task(
            fast_client(running.robot_ws_url(robot_of_client(running, i)), record, stop)
        )
        for i, record in enumerate(records)
    ]
    try:
        for _ in range(100):  # every client connected and streaming
            if all(r.frames for r in records):
                break
            await asyncio.sleep(0.1)
        load = await measure(running, args.seconds / args.cycles, watch_stall=watch_stall)
    finally:
        stop.set()
        await asyncio.gather(*tasks, return_exceptions=True)
    return load, records


async def run(args: argparse.Namespace, running: Stack) -> Results:
    """Baseline and load phases alternate (``--cycles`` times each), so both see the same
    machine: other processes' load drifts, and a ratio from two distant windows would
    measure that drift."""
    baselines: list[Phase] = []
    loads: list[Phase] = []
    records: list[list[ClientRecord]] = []
    staller: socket.socket | None = None
    stalled_after_s: float | None = None
    first = running.robot_names[0]
    for _ in range(args.cycles):
        baselines.append(await measure(running, args.baseline_seconds / args.cycles))
        if staller is None:  # one never-reading client, from the first load phase on
            staller = await never_reading_client(
                running.service_host, running.http_port, f"/api/v1/robots/{first}/stream"
            )
        load, cycle_records = await load_phase(args, running, stalled_after_s is None)
        if stalled_after_s is None and load.stalled_at_s is not None:
            stalled_after_s = sum(p.seconds for p in loads) + load.stalled_at_s
        loads.append(load)
        records.append(cycle_records)
    assert staller is not None
    cut = await socket_was_cut(staller)
    staller.close()
    final = metrics(running.get("/metrics").decode())
    return Results(
        functools.reduce(Phase.merged, baselines),
        functools.reduce(Phase.merged, loads),
        baselines,
        loads,
        records,
        cut,
        stalled_after_s,
        final,
    )


@dataclass
class Results:
    baseline: Phase
    load: Phase
    baselines: list[Phase]
    loads: list[Phase]
    records: list[list[ClientRecord]]
    """Per load phase, per client."""
    staller_cut: bool
    stalled_after_s: float | None
    final: dict[tuple[str, str], float]


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=1, help="emulated robots (default 1)")
    parser.add_argument("--rpi-ms", type=float, default=10.0)
    parser.add_argument("--clients", type=int, default=50, help="spread over the robots")
    parser.add_argument("--seconds", type=float, default=30.0, help="with clients, in all")
    parser.add_argument(
        "--baseline-seconds", type=float, default=20.0, help="without clients, in all"
    )
    parser.add_argument("--cycles", type=int, default=6, help="baseline/load alternations")
    parser.add_argument(
        "--robot-niceness",
        type=int,
        default=-10,
        help="nice value of the emulators (a real robot is its own machine; 0: same as the rest)",
    )
    parser.add_argument(
        "--cyclic-niceness", type=int, default=0, help="the service's cyclic_niceness setting"
    )
    parser.add_argument(
        "--service-source",
        type=Path,
        default=None,
        help="run the service of another commit: its backend/src, extension built in place "
        "(bench/fanout_sweep makes one)",
    )
    parser.add_argument(
        "--every-door",
        action="store_true",
        help="the whole cell: cycles and health on the demo program's cycles, the Sparkplug edge "
        "node on a local Mosquitto, the OPC UA server with a client on every variable "
        "(fanout_doors)",
    )
    parser.add_argument(
        "--opcua-interval-ms",
        type=float,
        default=fanout_doors.HISTORIAN_INTERVAL_MS,
        help="with --every-door: the OPC UA historian's publishing and sampling interval",
    )
    args = parser.parse_args()
    if not 1 <= args.robots <= 100 or args.clients < args.robots:
        parser.error("--robots: 1 to 100, and at least one client per robot")
    return args


def main() -> int:
    args = _arguments()
    service_args = ["--cyclic-niceness", str(args.cyclic_niceness)]
    with contextlib.ExitStack() as opened:
        doors = opened.enter_context(fanout_doors.doors()) if args.every_door else None
        running = opened.enter_context(
            stack(
                args.rpi_ms,
                *service_args,
                *(doors.service_args() if doors else ()),
                robot_niceness=args.robot_niceness,
                robots=args.robots,
                service_source=args.service_source,
                emulator_args=fanout_doors.EMULATOR_ARGS if doors else (),
            )
        )
        historian = (
            opened.enter_context(fanout_doors.opcua_client(doors, running, args.opcua_interval_ms))
            if doors
            else None
        )
        threads_before = fanout_doors.thread_cpu_s(running.service.pid)
        initial = metrics(running.get("/metrics").decode())  # the start's gaps not counted
        results = asyncio.run(run(args, running))
        threads_after = fanout_doors.thread_cpu_s(running.service.pid)
        if historian is not None:  # its figures before the service stops
            historian.finish()
        names = list(running.robot_names)
        client_robot = [robot_of_client(running, i) for i in range(args.clients)]
    print(
        f"bench/fanout: {args.robots} robot(s) at RPI {args.rpi_ms:g} ms, {args.clients} clients "
        f"at full rate spread over them + 1 never reading; {args.cycles} alternations of "
        f"{args.baseline_seconds / args.cycles:g} s without and "
        f"{args.seconds / args.cycles:g} s with clients; emulators at nice "
        f"{args.robot_niceness}, service cyclic thread at nice {args.cyclic_niceness}"
        + ("; every door open (fanout_doors)" if doors else "")
    )
    ratios = _report_robots(args, results, names, client_robot)
    lossless = _report_clients(args, results)
    _report_service(args, results)
    frames = results.baseline.frames_produced + results.load.frames_produced
    fanout_doors.report_threads(threads_before, threads_after, frames)
    within = all(r <= 1.2 for r in ratios.values())
    print(f"  targets: fast clients lose nothing: {lossless}; every ratio ≤ 1.2: {within}")
    whole = True
    if historian is not None:
        service_us = results.load.service_us_per_frame()
        whole = fanout_doors.report(
            results.final,
            initial,
            historian,
            service_us=service_us,
            ratios=ratios,
            clients_lossless=lossless,
        )
    return 0 if lossless and within and whole else 1


def _report_robots(
    args: argparse.Namespace, results: Results, names: list[str], client_robot: list[str]
) -> dict[str, float]:
    """Each robot's receive-interval p99 without and with clients (their ratio, returned)."""
    baseline, load = results.baseline, results.load
    per_client = [sum(cycle[i].frames for cycle in results.records) for i in range(args.clients)]
    ratios = {}
    for name in names:
        without, with_ = baseline.robots[name], load.robots[name]
        ratio = with_.p99_s / without.p99_s if without.p99_s else float("nan")
        ratios[name] = ratio
        median_with = statistics.median(p.robots[name].p99_s for p in results.loads)
        median_without = statistics.median(p.robots[name].p99_s for p in results.baselines)
        delivered = [per_client[i] for i in range(args.clients) if client_robot[i] == name]
        print(
            f"  robot {name}: receive interval p99 without {without.p99_s * 1e3:.2f} ms "
            f"({without.intervals} intervals), with {with_.p99_s * 1e3:.2f} ms "
            f"({with_.intervals}): ratio {ratio:.3f} (target ≤ 1.2); median of the phases' p99 "
            f"{median_with * 1e3:.2f} / {median_without * 1e3:.2f} ms = "
            f"{median_with / median_without:.3f}; p50 {without.p50_s * 1e3:.2f} / "
            f"{with_.p50_s * 1e3:.2f} ms; frames produced with clients {with_.frames_produced}, "
            f"delivered to each of its {len(delivered)} clients min {min(delivered)} / max "
            f"{max(delivered)}"
        )
    print(
        "  per phase p99 (ms), without: "
        + "; ".join(
            ", ".join(f"{p.robots[name].p99_s * 1e3:.2f}" for name in names)
            for p in results.baselines
        )
        + " | with: "
        + "; ".join(
            ", ".join(f"{p.robots[name].p99_s * 1e3:.2f}" for name in names) for p in results.loads
        )
    )
    return ratios


def _report_clients(args: argparse.Namespace, results: Results) -> bool:
    """What the fast clients got (and whether they lost nothing), and the never-reading one."""
    every = [r for cycle in results.records for r in cycle]
    missing = sum(r.missing for r in every)
    told = sum(r.dropped_told for r in every)
    disorder = sum(r.seqs_out_of_order for r in every)
    closed = [r.closed for r in every if r.closed]
    latencies = sorted(x for r in every for x in r.latencies_s)
    print(
        f"  fast clients: frames missed {missing}, dropped notices {told}, out of order "
        f"{disorder}, closed by the server {len(closed)}"
    )
    if every:
        messages = sum(r.frames_messages for r in every)
        frames = sum(r.frames for r in every)
        connected_s = sum(r.connected_s for r in every)
        print(
            "  frames messages per fast client per second "
            f"{messages / max(connected_s, 1e-9):.1f} ({frames / max(messages, 1):.1f} frames"
            f" each; {sum(r.messages for r in every) - messages} status, event and other"
            " messages)"
        )
    if latencies:
        print(
            "  frame age when read (receive → client): "
            f"p50 {latencies[len(latencies) // 2] * 1e3:.1f} ms, "
            f"p99 {latencies[int(len(latencies) * 0.99)] * 1e3:.1f} ms"
        )
    stalled = _total(results, "ws_stalled_disconnects_total")
    after = results.stalled_after_s
    when = f" after {after:.0f} s" if after is not None else ""
    print(
        f"  never-reading client: disconnected by the service{when}: {bool(stalled)}; "
        f"its socket reset/closed: {results.staller_cut}"
    )
    return missing == 0 and told == 0 and not closed


def _total(results: Results, name: str) -> float:
    """A service total, summed over the robots' labels."""
    return sum(v for (metric, _), v in results.final.items() if metric == "cobot_hmi_" + name)


def _report_service(args: argparse.Namespace, results: Results) -> None:
    """The service's CPU per robot-frame and its totals."""
    baseline, load = results.baseline, results.load
    print(
        f"  service CPU per robot-frame: with clients {load.service_us_per_frame():.0f} µs "
        f"({load.frames_produced} frames of {args.robots} robot(s)), without "
        f"{baseline.service_us_per_frame():.0f} µs ({baseline.frames_produced} frames)"
    )
    print(
        f"  CPU with clients: service {load.cpu_percent(load.service_cpu_s):.1f} %, emulators "
        f"{load.cpu_percent(load.emulator_cpu_s):.1f} %, clients (this process) "
        f"{load.cpu_percent(load.bench_cpu_s):.1f} %; without: service "
        f"{baseline.cpu_percent(baseline.service_cpu_s):.1f} %  (100 % = one core; "
        f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f})"
    )
    print(
        f"  service totals: ws frames sent {_total(results, 'ws_frames_sent_total'):.0f}, "
        f"ws dropped {_total(results, 'ws_dropped_frames_total'):.0f} (the never-reading "
        f"client's), hub frames lost {_total(results, 'hub_frames_lost_total'):.0f}, "
        f"T→O gaps {_total(results, 'frame_gaps_total'):.0f}"
    )


if __name__ == "__main__":
    raise SystemExit(main())
