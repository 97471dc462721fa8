"""Benchmark of issue 3 (``bench/cyclic``): class 1 I/O against explicit polling.

1. The emulator runs as its own process (so its CPU is its own), on a fresh loopback address.
2. Our originator holds an exclusive-owner connection (idle) at the RPI for the run's length;
   T→O is measured where it arrives (this process, when its callback runs), O→T where it
   arrives (the emulator, from the kernel's receive times, read from its control API's
   status). Per direction: packets, gaps, interval p50/p99/max.
3. In the same run, pycomm3 polls assembly 100 with explicit reads (decoding each distinct
   frame, as the class 1 path does) as fast as it can: the issue's comparison.
4. For context only, the same reads once per RPI ("paced"): what polling costs per frame when
   it delivers what class 1 delivers.

Steps 2 and 3 alternate in rounds (4 by default: 5 s of class 1 on a fresh connection, then
2.5 s of polling, four times), because this machine's speed drifts over a minute with what else
it runs: a class 1 phase and a polling phase minutes apart would compare the machine's moods.
The CPU target is the median of the rounds' ratios; the totals of all rounds are printed too.
Printed: each figure, each process's CPU %, CPU per frame for both ways (both processes
together, the target's definition, then the scanner's and the emulator's share), wake-ups per
frame (voluntary context switches: each costs far more CPU than the packet it serves), the load
average before and after, and the targets of issue 3 (zero gaps, interval p99 within 0.5 ms of the
RPI, less CPU per frame than polling).

CPU per frame is the robust figure on a busy machine; interval percentiles measure the machine's
scheduling as much as the code when other work competes for the cores, so compare them only on a
quiet machine (the load average is printed for that reason). A connection lost and reopened during
the run counts against "zero gaps": the packets it missed carry no sequence count to miss.
"""

from __future__ import annotations

import argparse
import asyncio
import itertools
import json
import os
import random
import socket
import statistics
import subprocess
import sys
import time
import urllib.request
from typing import Any

from proc_stats import load_average, own_cpu_s, process_cpu_s, wakeups

from cobot_hmi.codec import Frame, decode_frame
from cobot_hmi.eventloop import freeze_startup_heap, precise_event_loop
from cobot_hmi.scanner.explicit import ExplicitReader
from cobot_hmi.scanner.originator import ConnectionState, Originator, OriginatorSettings


class Meter:
    """CPU seconds and wake-ups of this process (the scanner or poller) and of the emulator."""

    def __init__(self, emulator_pid: int) -> None:
        self.emulator_pid = emulator_pid
        self.start = self._read()

    def _read(self) -> tuple[float, float, int, int, float]:
        pid = self.emulator_pid
        return (
            own_cpu_s(),
            process_cpu_s(pid),
            wakeups(os.getpid()),
            wakeups(pid),
            time.monotonic(),
        )

    def figures(self, frames: int) -> dict[str, float]:
        end = self._read()
        own_s, emu_s, own_wakes, emu_wakes, wall_s = (
            b - a for a, b in zip(self.start, end, strict=True)
        )
        return derive(
            {
                "own_s": own_s,
                "emu_s": emu_s,
                "own_wakes": own_wakes,
                "emu_wakes": emu_wakes,
                "wall_s": wall_s,
                "frames": frames,
            }
        )


RAW_KEYS = ("own_s", "emu_s", "own_wakes", "emu_wakes", "wall_s", "frames")


def derive(raw: dict[str, float]) -> dict[str, float]:
    """The printed figures from raw CPU seconds, wake-ups, wall time and frames."""
    wall_s, frames = raw["wall_s"], max(raw["frames"], 1)
    own_s, emu_s = raw["own_s"], raw["emu_s"]
    return {
        **raw,
        "frames_per_s": frames / wall_s,
        "scanner_cpu_pct": 100 * own_s / wall_s,
        "emulator_cpu_pct": 100 * emu_s / wall_s,
        "cpu_us_per_frame": 1e6 * (own_s + emu_s) / frames,
        "scanner_cpu_us_per_frame": 1e6 * own_s / frames,
        "emulator_cpu_us_per_frame": 1e6 * emu_s / frames,
        "scanner_wakeups_per_frame": raw["own_wakes"] / frames,
        "emulator_wakeups_per_frame": raw["emu_wakes"] / frames,
    }


def combine(rounds: list[dict[str, Any]]) -> dict[str, float]:
    """The CPU figures of several rounds together (sums of the raw values)."""
    return derive({key: sum(r[key] for r in rounds) for key in RAW_KEYS})


def free_port(host: str, kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


def percentile(values: list[float], share: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(len(ordered) * share))]


def fmt(value: float | None, unit: str = "") -> str:
    return "n/a" if value is None else f"{value:.3f}{unit}"


async def run_class1(  # noqa: PLR0917
    robot_host: str,
    tcp_port: int,
    plc_host: str,
    rpi_us: int,
    seconds: float,
    emulator_pid: int,
    control_port: int,
) -> dict[str, Any]:
    arrivals: list[float] = []
    losses: list[str] = []

    def on_frame(frame: Frame, payload: bytes, received_at: float, seq: int) -> None:
        arrivals.append(received_at)  # the kernel's receive time (frames are read in batches)

    def on_state(state: ConnectionState, reason: str | None) -> None:
        if state in (ConnectionState.LOST, ConnectionState.REFUSED):
            losses.append(f"{state}: {reason}")

    originator = Originator(
        OriginatorSettings(robot_host, tcp_port, local_host=plc_host, rpi_us=rpi_us),
        on_frame=on_frame,
        on_state=on_state,
    )
    await originator.start()
    try:
        if not await originator.wait_connected(10):
            raise SystemExit(f"no connection: {originator.state} {originator.reason}")
        await asyncio.sleep(1.0)  # warm-up
        before, pump_before = originator.stats(), originator.pump_counters()
        arrivals.clear()
        losses.clear()
        meter = Meter(emulator_pid)
        await asyncio.sleep(seconds)
        figures = meter.figures(len(arrivals))
        after, pump_after = originator.stats(), originator.pump_counters()
        status = await asyncio.to_thread(fetch_status, robot_host, control_port)
    finally:
        await originator.stop()
    intervals_ms = [(b - a) * 1e3 for a, b in itertools.pairwise(arrivals)]
    connections = status["connections"]
    connection = connections[0] if connections else {}
    return {
        "t2o": {
            "packets": after.packets_in - before.packets_in,
            "gaps": after.gaps - before.gaps,
            "p50_ms": percentile(intervals_ms, 0.5) if intervals_ms else None,
            "p99_ms": percentile(intervals_ms, 0.99) if intervals_ms else None,
            "max_ms": max(intervals_ms) if intervals_ms else None,
        },
        "o2t": {
            "packets": after.packets_out - before.packets_out,
            "gaps": connection.get("o2t_gaps"),
            "p50_ms": connection.get("o2t_interval_p50_ms"),
            "p99_ms": connection.get("o2t_interval_p99_ms"),
            "max_ms": connection.get("o2t_interval_max_ms"),
            "note": "gaps/intervals measured by the emulator over its current connection",
        },
        "scanner_pump": {
            "wakeups": pump_after["wakeups"] - pump_before["wakeups"],
            "max_late_ms": pump_after["max_late_ns"] / 1e6,
            "realtime": bool(pump_after.get("realtime")),
        },
        "emulator_pump": status.get("pump", {}),
        "losses": losses,
        "t2o_intervals_ms": intervals_ms,
        **figures,
    }


def fetch_status(host: str, port: int) -> dict[str, Any]:
    opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))  # loopback: no proxy
    with opener.open(f"http://{host}:{port}/status", timeout=5) as reply:
        data: dict[str, Any] = json.loads(reply.read())
        return data


def run_polling(
    robot_host: str,
    tcp_port: int,
    seconds: float,
    emulator_pid: int,
    period_s: float = 0.0,
) -> dict[str, Any]:
    """pycomm3 reads of assembly 100, each decoded: back to back (``period_s`` 0, the issue's
    comparison), or one per ``period_s`` on a drift-free schedule (context only)."""
    frames = 0
    with ExplicitReader(robot_host, tcp_port) as reader:
        reader.read_assembly(100)
        meter = Meter(emulator_pid)
        deadline = start = time.monotonic()
        end = start + seconds
        last: tuple[bytes, Frame] | None = None
        while time.monotonic() < end:
            data = reader.read_assembly(100)
            # Decoded once per distinct frame, as the class 1 path does (a robot's monitoring
            # values refresh about every 100 ms): the same work per frame on both sides.
            if last is None or data != last[0]:
                last = (data, decode_frame(data))
            frames += 1
            if period_s:
                deadline += period_s
                time.sleep(max(0.0, deadline - time.monotonic()))
        figures = meter.figures(frames)
    return {"frames": frames, **figures}


def combine_class1(rounds: list[dict[str, Any]]) -> dict[str, Any]:
    """The class 1 rounds as one run: T→O intervals pooled; O→T (measured by the emulator per
    connection) summed, its p50 the median round's, its p99 and max the worst round's."""
    intervals_ms = [i for r in rounds for i in r["t2o_intervals_ms"]]
    o2t = [r["o2t"] for r in rounds]

    def worst(key: str) -> float | None:
        values = [d[key] for d in o2t if d[key] is not None]
        return max(values) if values else None

    p50s = [d["p50_ms"] for d in o2t if d["p50_ms"] is not None]
    return {
        **combine(rounds),
        "t2o": {
            "packets": sum(r["t2o"]["packets"] for r in rounds),
            "gaps": sum(r["t2o"]["gaps"] for r in rounds),
            "p50_ms": percentile(intervals_ms, 0.5) if intervals_ms else None,
            "p99_ms": percentile(intervals_ms, 0.99) if intervals_ms else None,
            "max_ms": max(intervals_ms) if intervals_ms else None,
        },
        "o2t": {
            "packets": sum(d["packets"] for d in o2t),
            "gaps": sum(d["gaps"] or 0 for d in o2t),
            "p50_ms": statistics.median_high(p50s) if p50s else None,
            "p99_ms": worst("p99_ms"),
            "max_ms": worst("max_ms"),
        },
        "losses": [loss for r in rounds for loss in r["losses"]],
        "scanner_pump": {
            "wakeups": sum(r["scanner_pump"]["wakeups"] for r in rounds),
            "max_late_ms": max(r["scanner_pump"]["max_late_ms"] for r in rounds),
            "realtime": all(r["scanner_pump"]["realtime"] for r in rounds),
        },
        "emulator_pump": rounds[-1]["emulator_pump"],
        "rounds": [{k: v for k, v in r.items() if k != "t2o_intervals_ms"} for r in rounds],
    }


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rpi-ms", type=float, default=2.0)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--poll-seconds", type=float, default=10.0)
    parser.add_argument(
        "--kinematic-refresh-ms",
        type=float,
        default=None,
        help="pass to the emulator (default: the emulator's, 100 ms as the real controller; "
        "0: fresh values in every frame)",
    )
    parser.add_argument(
        "--rounds",
        type=int,
        default=4,
        help="split both into this many alternating rounds (class 1, then polling), so a change "
        "in the machine's load hits both ways alike; the CPU target is the median of the "
        "rounds' ratios",
    )
    parser.add_argument(
        "--paced-seconds",
        type=float,
        default=5.0,
        help="also poll once per RPI for this long, for context (0: skip)",
    )
    parser.add_argument(
        "--robots",
        default=None,
        metavar="N[,N…]",
        help="instead: one originator process holding N connections to N emulators on one UDP "
        "socket, for each N, with the C pump and the pure-Python one (bench/cyclic_robots.py)",
    )
    return parser.parse_args()


def main() -> int:
    args = _arguments()
    if args.robots is not None:
        from cyclic_robots import bench as robots_bench

        robots = [int(n) for n in args.robots.split(",")]
        return robots_bench(robots, args.rpi_ms, args.seconds)
    rng = random.Random()
    robot_host = f"127.{rng.randint(100, 250)}.{rng.randint(0, 250)}.{rng.randint(2, 250)}"
    plc_host = f"127.{rng.randint(100, 250)}.{rng.randint(0, 250)}.{rng.randint(2, 250)}"
    tcp_port = free_port(robot_host, socket.SOCK_STREAM)
    control_port = free_port(robot_host, socket.SOCK_STREAM)
    command = [
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "emulator",
        "--host",
        robot_host,
        "--tcp-port",
        str(tcp_port),
        "--control-port",
        str(control_port),
        *(
            ["--kinematic-refresh-ms", str(args.kinematic_refresh_ms)]
            if args.kinematic_refresh_ms is not None
            else []
        ),
    ]
    emulator = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        results = _measure(args, emulator, robot_host, tcp_port, plc_host, control_port)
    finally:
        emulator.terminate()
        emulator.wait(10)
        if emulator.stdout is not None:
            emulator.stdout.close()
    report(args, *results)
    return 0


def _measure(  # noqa: PLR0917
    args: argparse.Namespace,
    emulator: subprocess.Popen[bytes],
    robot_host: str,
    tcp_port: int,
    plc_host: str,
    control_port: int,
) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any] | None, tuple[str, str]]:
    """The class 1 and polling rounds against the running emulator, then the paced reads:
    their figures and the load averages before and after."""
    assert emulator.stdout is not None
    banner = emulator.stdout.readline().decode().strip()
    if "EtherNet/IP target" not in banner:
        raise SystemExit(f"emulator did not start: {banner!r}")
    rpi_us = round(args.rpi_ms * 1000)
    load_before = load_average()
    freeze_startup_heap()  # as the scan verb does: no full collection stalls the schedule
    class1_rounds: list[dict[str, Any]] = []
    polling_rounds: list[dict[str, Any]] = []
    with asyncio.Runner(loop_factory=precise_event_loop) as runner:
        for _ in range(args.rounds):
            class1_rounds.append(
                runner.run(
                    run_class1(
                        robot_host,
                        tcp_port,
                        plc_host,
                        rpi_us,
                        args.seconds / args.rounds,
                        emulator.pid,
                        control_port,
                    )
                )
            )
            polling_rounds.append(
                run_polling(robot_host, tcp_port, args.poll_seconds / args.rounds, emulator.pid)
            )
    class1 = combine_class1(class1_rounds)
    polling = {**combine(polling_rounds), "rounds": polling_rounds}
    paced = (
        run_polling(robot_host, tcp_port, args.paced_seconds, emulator.pid, args.rpi_ms / 1e3)
        if args.paced_seconds > 0
        else None
    )
    load_after = load_average()
    return class1, polling, paced, (load_before, load_after)


def report(
    args: argparse.Namespace,
    class1: dict[str, Any],
    polling: dict[str, Any],
    paced: dict[str, Any] | None,
    loads: tuple[str, str],
) -> None:
    rpi_ms = args.rpi_ms
    print(
        f"bench/cyclic: RPI {rpi_ms} ms, {args.seconds:g} s class 1, "
        f"{args.poll_seconds:g} s polling, in {args.rounds} alternating rounds, simulated robot"
        + (
            f" (monitoring refresh {args.kinematic_refresh_ms:g} ms)"
            if args.kinematic_refresh_ms is not None
            else " (monitoring values refresh every 100 ms, the emulator's default, as the real"
            " controller's)"
        )
        + "; "
        f"load average {loads[0]} before, {loads[1]} after (2 cores: compare latency only when low)"
    )
    for name in ("t2o", "o2t"):
        d = class1[name]
        print(
            f"  {name.upper():4} packets {d['packets']:6d}  gaps {d['gaps']}  interval p50 "
            f"{fmt(d['p50_ms'], ' ms')}  p99 {fmt(d['p99_ms'], ' ms')}  "
            f"max {fmt(d['max_ms'], ' ms')}"
        )
    pump = class1["scanner_pump"]
    emulator_pump = class1["emulator_pump"]
    print(
        f"  cyclic pumps: scanner {pump['wakeups'] / max(class1['frames'], 1):.2f} wake-ups per "
        f"frame, latest O→T send {pump['max_late_ms']:.3f} ms after its due time (since start); "
        f"latest T→O send {emulator_pump.get('max_late_ns', 0) / 1e6:.3f} ms; real-time priority: "
        f"scanner {'yes' if pump['realtime'] else 'no'}, "
        f"emulator {'yes' if emulator_pump.get('realtime') else 'no'}"
    )
    _report_cpu(class1, polling, paced)
    _report_targets(rpi_ms, class1, polling)
    print(json.dumps({"class1": class1, "polling": polling, "paced": paced, "load_average": loads}))


def _report_cpu(
    class1: dict[str, Any], polling: dict[str, Any], paced: dict[str, Any] | None
) -> None:
    """The losses and the CPU and wake-ups per frame of class 1, polling and paced polling."""
    losses = class1["losses"]
    print(f"  connection losses {len(losses)}" + (f": {'; '.join(losses)}" if losses else ""))
    print(
        "                frames/s    CPU/frame: both  scanner  emulator   "
        "wake-ups/frame: scanner  emulator   CPU %: scanner  emulator"
    )
    rows = [("class 1", class1), ("polling", polling)]
    if paced is not None:
        rows.append(("paced", paced))
    for name, d in rows:
        print(
            f"  {name:9} {d['frames_per_s']:10.1f}  {d['cpu_us_per_frame']:13.1f} µs "
            f"{d['scanner_cpu_us_per_frame']:5.1f} µs {d['emulator_cpu_us_per_frame']:6.1f} µs  "
            f"{d['scanner_wakeups_per_frame']:20.2f} {d['emulator_wakeups_per_frame']:9.2f}  "
            f"{d['scanner_cpu_pct']:13.1f} {d['emulator_cpu_pct']:9.1f}"
        )
    print(
        "  (polling: the scanner column is the pycomm3 poller, reading back to back as the issue"
        " compares; paced: the same reads once per RPI, for context, not a target)"
    )


def _report_targets(rpi_ms: float, class1: dict[str, Any], polling: dict[str, Any]) -> None:
    """Gaps, jitter and CPU against polling, round by round, and the three targets."""
    losses = class1["losses"]
    gaps_ok = class1["t2o"]["gaps"] == 0 and class1["o2t"]["gaps"] == 0 and not losses
    p99s = [class1[n]["p99_ms"] for n in ("t2o", "o2t")]
    jitter_ok = all(p is not None and abs(p - rpi_ms) <= 0.5 for p in p99s)
    ratios = [
        c["cpu_us_per_frame"] / p["cpu_us_per_frame"]
        for c, p in zip(class1["rounds"], polling["rounds"], strict=True)
    ]
    median_ratio = statistics.median(ratios)
    print(
        "  CPU per frame, class 1 / polling, round by round: "
        + ", ".join(
            f"{c['cpu_us_per_frame']:.0f}/{p['cpu_us_per_frame']:.0f} µs = {r:.2f}"
            for c, p, r in zip(class1["rounds"], polling["rounds"], ratios, strict=True)
        )
        + f"; median {median_ratio:.2f} (all rounds together "
        f"{class1['cpu_us_per_frame'] / polling['cpu_us_per_frame']:.2f})"
    )
    cpu_ok = median_ratio < 1
    print(
        "  targets: zero gaps "
        + ("MET" if gaps_ok else "MISSED")
        + "; p99 within 0.5 ms of the RPI "
        + ("MET" if jitter_ok else "MISSED")
        + "; less CPU per frame than polling (median of the rounds' ratios < 1) "
        + ("MET" if cpu_ok else "MISSED")
    )


if __name__ == "__main__":
    sys.exit(main())
