"""Benchmark of issue 3 (``bench/cyclic``): class 1 I/O against explicit polling.

1. The emulator runs as its own process (so its CPU is its own), on a fresh loopback address.
2. Our originator holds an exclusive-owner connection (idle) at the RPI for the run's length;
   T→O is measured where it arrives (this process), O→T where it arrives (the emulator, read
   from its control API's status). Per direction: packets, gaps, interval p50/p99/max.
3. In the same run, pycomm3 polls assembly 100 with explicit reads (decoding each frame, as the
   class 1 path does) as fast as it can.
Printed: each figure, each process's CPU %, CPU per frame for both ways, and the targets of
issue 3 (zero gaps, interval p99 within 0.5 ms of the RPI, less CPU per frame than polling).
"""

from __future__ import annotations

import argparse
import asyncio
import itertools
import json
import os
import random
import socket
import subprocess
import sys
import time
import urllib.request
from typing import Any

from cobot_hmi.codec import Frame, decode_frame
from cobot_hmi.eventloop import precise_event_loop
from cobot_hmi.scanner.explicit import ExplicitReader
from cobot_hmi.scanner.originator import Originator, OriginatorSettings

CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def process_cpu_s(pid: int) -> float:
    """User + system CPU seconds of a process, from /proc."""
    with open(f"/proc/{pid}/stat") as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS


def own_cpu_s() -> float:
    times = os.times()
    return times.user + times.system


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
    loop = asyncio.get_running_loop()

    def on_frame(frame: Frame, received_at: float, seq: int) -> None:
        arrivals.append(loop.time())

    originator = Originator(
        OriginatorSettings(robot_host, tcp_port, local_host=plc_host, rpi_us=rpi_us),
        on_frame=on_frame,
    )
    await originator.start()
    try:
        if not await originator.wait_connected(10):
            raise SystemExit(f"no connection: {originator.state} {originator.reason}")
        await asyncio.sleep(1.0)  # warm-up
        before = originator.stats()
        arrivals.clear()
        cpu0, emu0, wall0 = own_cpu_s(), process_cpu_s(emulator_pid), time.monotonic()
        await asyncio.sleep(seconds)
        cpu1, emu1, wall1 = own_cpu_s(), process_cpu_s(emulator_pid), time.monotonic()
        after = originator.stats()
        status = await asyncio.to_thread(fetch_status, robot_host, control_port)
    finally:
        await originator.stop()
    intervals_ms = [(b - a) * 1e3 for a, b in itertools.pairwise(arrivals)]
    connection = status["connections"][0]
    wall = wall1 - wall0
    frames = len(arrivals)
    return {
        "t2o": {
            "packets": after.packets_in - before.packets_in,
            "gaps": after.gaps - before.gaps,
            "p50_ms": percentile(intervals_ms, 0.5),
            "p99_ms": percentile(intervals_ms, 0.99),
            "max_ms": max(intervals_ms),
        },
        "o2t": {
            "packets": after.packets_out - before.packets_out,
            "gaps": connection.get("o2t_gaps"),
            "p50_ms": connection.get("o2t_interval_p50_ms"),
            "p99_ms": connection.get("o2t_interval_p99_ms"),
            "max_ms": connection.get("o2t_interval_max_ms"),
            "note": "gaps/intervals measured by the emulator over the whole connection",
        },
        "frames": frames,
        "frames_per_s": frames / wall,
        "scanner_cpu_pct": 100 * (cpu1 - cpu0) / wall,
        "emulator_cpu_pct": 100 * (emu1 - emu0) / wall,
        "cpu_us_per_frame": 1e6 * ((cpu1 - cpu0) + (emu1 - emu0)) / max(frames, 1),
    }


def fetch_status(host: str, port: int) -> dict[str, Any]:
    opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))  # loopback: no proxy
    with opener.open(f"http://{host}:{port}/status", timeout=5) as reply:
        data: dict[str, Any] = json.loads(reply.read())
        return data


def run_polling(
    robot_host: str, tcp_port: int, seconds: float, emulator_pid: int
) -> dict[str, Any]:
    frames = 0
    with ExplicitReader(robot_host, tcp_port) as reader:
        reader.read_assembly(100)
        cpu0, emu0, wall0 = own_cpu_s(), process_cpu_s(emulator_pid), time.monotonic()
        end = wall0 + seconds
        while time.monotonic() < end:
            decode_frame(reader.read_assembly(100))
            frames += 1
        cpu1, emu1, wall1 = own_cpu_s(), process_cpu_s(emulator_pid), time.monotonic()
    wall = wall1 - wall0
    return {
        "frames": frames,
        "frames_per_s": frames / wall,
        "poller_cpu_pct": 100 * (cpu1 - cpu0) / wall,
        "emulator_cpu_pct": 100 * (emu1 - emu0) / wall,
        "cpu_us_per_frame": 1e6 * ((cpu1 - cpu0) + (emu1 - emu0)) / max(frames, 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rpi-ms", type=float, default=2.0)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--poll-seconds", type=float, default=10.0)
    args = parser.parse_args()
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
    ]
    emulator = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        assert emulator.stdout is not None
        banner = emulator.stdout.readline().decode().strip()
        if "EtherNet/IP target" not in banner:
            raise SystemExit(f"emulator did not start: {banner!r}")
        rpi_us = round(args.rpi_ms * 1000)
        with asyncio.Runner(loop_factory=precise_event_loop) as runner:
            class1 = runner.run(
                run_class1(
                    robot_host, tcp_port, plc_host, rpi_us, args.seconds, emulator.pid, control_port
                )
            )
        polling = run_polling(robot_host, tcp_port, args.poll_seconds, emulator.pid)
    finally:
        emulator.terminate()
        emulator.wait(10)
        if emulator.stdout is not None:
            emulator.stdout.close()

    rpi_ms = args.rpi_ms
    print(
        f"bench/cyclic: RPI {rpi_ms} ms, {args.seconds:g} s class 1, "
        f"{args.poll_seconds:g} s polling, simulated robot"
    )
    for name in ("t2o", "o2t"):
        d = class1[name]
        print(
            f"  {name.upper():4} packets {d['packets']:6d}  gaps {d['gaps']}  interval p50 "
            f"{fmt(d['p50_ms'], ' ms')}  p99 {fmt(d['p99_ms'], ' ms')}  "
            f"max {fmt(d['max_ms'], ' ms')}"
        )
    print(
        f"  class 1:  {class1['frames_per_s']:8.1f} frames/s  scanner CPU "
        f"{class1['scanner_cpu_pct']:5.1f} %  emulator CPU {class1['emulator_cpu_pct']:5.1f} %  "
        f"{class1['cpu_us_per_frame']:7.1f} µs CPU/frame"
    )
    print(
        f"  polling:  {polling['frames_per_s']:8.1f} frames/s  poller CPU "
        f"{polling['poller_cpu_pct']:5.1f} %  emulator CPU {polling['emulator_cpu_pct']:5.1f} %  "
        f"{polling['cpu_us_per_frame']:7.1f} µs CPU/frame"
    )
    gaps_ok = class1["t2o"]["gaps"] == 0 and class1["o2t"]["gaps"] == 0
    p99s = [class1[n]["p99_ms"] for n in ("t2o", "o2t") if class1[n]["p99_ms"] is not None]
    jitter_ok = all(abs(p - rpi_ms) <= 0.5 for p in p99s)
    cpu_ok = class1["cpu_us_per_frame"] < polling["cpu_us_per_frame"]
    print(
        "  targets: zero gaps "
        + ("MET" if gaps_ok else "MISSED")
        + "; p99 within 0.5 ms of the RPI "
        + ("MET" if jitter_ok else "MISSED")
        + "; less CPU per frame than polling "
        + ("MET" if cpu_ok else "MISSED")
    )
    print(json.dumps({"class1": class1, "polling": polling}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
