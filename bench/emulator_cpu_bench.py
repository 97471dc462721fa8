"""``bench/emulator_cpu``: what one emulated robot costs the machine it runs on while a class 1
connection holds it (issue 40: 32 emulators beside the service on a 2-core machine).

N emulators start (``cobot-hmi emulator``, each its own process and loopback address, the demo
program with its cycle marker on bit output register 63), one originator process
(``bench/cyclic_robots.py --originator``) holds a connection to each at the RPI, and after a
warm-up each emulator's CPU (all its threads: the event loop's and the cyclic pump's) and
wake-ups are read from /proc over the run.

``--compare-src DIR`` starts as many emulators again from another source tree (say
``git archive <commit> backend/src`` unpacked, with the built ``native`` extension copied in),
side by side in the same run, so both meet the same machine: the A/B to trust on a busy one.
Printed: per side, CPU % of a core per emulator (mean, max), wake-ups per second per emulator,
the load average before and after, and the originator's T→O gaps (none expected).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import time
from pathlib import Path

from cyclic_robots import free_port
from proc_stats import load_average, process_cpu_s, wakeups

HERE = Path(__file__).resolve().parent


def start(
    count: int, src: str | None, octet: int, first: int
) -> list[tuple[subprocess.Popen[bytes], str]]:
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = src
    started = []
    for n in range(count):
        host = f"127.{octet}.0.{first + n}"
        tcp_port, control_port = free_port(host), free_port(host)
        command = [
            sys.executable, "-m", "cobot_hmi.cli", "emulator", "--host", host,
            "--tcp-port", str(tcp_port), "--control-port", str(control_port),
            "--seed", str(n + 1), "--cycle-marker-register", "63",
        ]  # fmt: skip
        process = subprocess.Popen(
            command, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL
        )
        assert process.stdout is not None
        banner = process.stdout.readline().decode().strip()
        if "EtherNet/IP target" not in banner:
            raise SystemExit(f"emulator {host} did not start: {banner!r}")
        started.append((process, f"{host}:{tcp_port}:{control_port}"))
    return started


def side_figures(
    pids: list[int], cpu0: dict[int, float], wake0: dict[int, int], wall_s: float
) -> str:
    cpu = [100 * (process_cpu_s(p) - cpu0[p]) / wall_s for p in pids]
    wakes = [(wakeups(p) - wake0[p]) / wall_s for p in pids]
    return (
        f"CPU per emulator {sum(cpu) / len(cpu):.2f} % of a core (max {max(cpu):.2f}), "
        f"wake-ups {sum(wakes) / len(wakes):.0f}/s per emulator"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=8, help="emulators per side")
    parser.add_argument("--rpi-ms", type=float, default=10.0)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--warm-up-s", type=float, default=5.0)
    parser.add_argument("--compare-src", help="another source tree's backend/src: the A side")
    args = parser.parse_args()
    octet = random.randint(100, 250)
    sides: dict[str, list[tuple[subprocess.Popen[bytes], str]]] = {}
    try:
        sides["this tree"] = start(args.robots, None, octet, 2)
        if args.compare_src:
            sides[f"--compare-src {args.compare_src}"] = start(
                args.robots, args.compare_src, octet, 2 + args.robots
            )
        everyone = [entry for started in sides.values() for entry in started]
        originator = subprocess.Popen(
            [
                sys.executable, str(HERE / "cyclic_robots.py"), "--originator",
                "--targets", ",".join(target for _, target in everyone),
                "--plc-host", f"127.{octet}.1.1", "--rpi-us", str(round(args.rpi_ms * 1000)),
                "--seconds", str(args.warm_up_s + args.seconds),
            ],
            stdout=subprocess.PIPE,
        )  # fmt: skip
        # The connections open and settle (the originator waits 1 s more).
        time.sleep(args.warm_up_s)
        pids = [process.pid for process, _ in everyone]
        load_before = load_average()
        cpu0 = {p: process_cpu_s(p) for p in pids}
        wake0 = {p: wakeups(p) for p in pids}
        wall0 = time.monotonic()
        time.sleep(args.seconds)
        wall_s = time.monotonic() - wall0
        lines = [
            f"{name}: " + side_figures([p.pid for p, _ in started], cpu0, wake0, wall_s)
            for name, started in sides.items()
        ]
        out, _ = originator.communicate(timeout=args.warm_up_s + args.seconds + 60)
        result = json.loads(out.decode().splitlines()[-1])
    finally:
        for started in sides.values():
            for process, _ in started:
                process.terminate()
                process.wait(10)
    gaps = sum(c["t2o_gaps"] for c in result["connections"])
    print(f"{args.robots} emulator(s) per side, RPI {args.rpi_ms:g} ms, {args.seconds:g} s")
    for line in lines:
        print("  " + line)
    print(
        f"  T→O gaps {gaps}, losses {len(result['losses'])}; load {load_before} -> {load_average()}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
