"""Benchmark of issue 40 (``bench/health``): what reading every robot's health costs the cell.

``--robots`` emulated robots (16) running the demo program with its cycle marker, the service
holding a class 1 connection to each at ``--rpi-ms`` (10 ms) and measuring their cycles, with
health off (``--no-health-enabled``) and on (the shipped settings), alternating ``--cycles``
times on the same emulators so that both conditions see the same machine (other processes'
load drifts). Each service restart finds the state of the one before it in the same state
directory: the first one with health on is given a baseline to learn (``--baseline-cycles``
of each robot's next cycles, through the REST API as an operator), the later ones go on
learning or judging from it, as a cell does across restarts.

Per condition, merged over its phases (``--seconds`` each, after ``--settle-seconds``):
- the health thread's CPU per robot-frame (``cobot_hmi_health_cpu_seconds_total`` over the
  frames received): the cost the target bounds (≤ 15 µs);
- the service's CPU per robot-frame with health on and off, and the difference (the same cost
  seen from outside: it includes the frame hand-over, the events and the saves);
- per robot the cyclic receive interval p99 (``cobot_hmi_frame_receive_interval_seconds``)
  with health on over the one with health off; the worst ratio (target ≤ 1.05);
- T→O gaps (``cobot_hmi_frame_gaps_total``; target 0) and the frames health's queue dropped
  (``cobot_hmi_consumer_dropped_frames_total{consumer="health"}``).
At the end: each robot's health as the service reads it (baseline learned or learning, the
cycles judged, the worst verdict), so a run shows health did its work, not merely ran.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import httpx
import orjson
from fanout_bench import HISTOGRAM, Phase, measure
from service_bench_support import (
    BENCH_USER,
    Stack,
    emulated_cell,
    histogram_quantile,
    labels_of,
    metrics,
    serving,
)

CYCLE_MARKER_REGISTER = 63
"""The demo program's cycle-start marker (as ``cobot-hmi demo`` runs it)."""
CYCLE_TRIGGER = f"bit_output_registers.{CYCLE_MARKER_REGISTER}:rising"
TARGET_HEALTH_US = 15.0
TARGET_RATIO = 1.05


@dataclass
class Totals:
    """Service-wide counters taken between a phase's two scrapes."""

    health_cpu_s: float = 0.0
    gaps: float = 0.0
    health_dropped: float = 0.0


@dataclass
class Condition:
    """One condition's phases, merged."""

    phase: Phase | None = None
    totals: Totals = field(default_factory=Totals)

    def add(self, phase: Phase, totals: Totals) -> None:
        self.phase = phase if self.phase is None else self.phase.merged(phase)
        self.totals.health_cpu_s += totals.health_cpu_s
        self.totals.gaps += totals.gaps
        self.totals.health_dropped += totals.health_dropped


def _sum(samples: dict[tuple[str, str], float], name: str, consumer: str | None = None) -> float:
    return sum(
        value
        for (metric, labels), value in samples.items()
        if metric == name and (consumer is None or labels_of(labels).get("consumer") == consumer)
    )


def _totals(before: dict[tuple[str, str], float], after: dict[tuple[str, str], float]) -> Totals:
    def delta(name: str, consumer: str | None = None) -> float:
        return _sum(after, name, consumer) - _sum(before, name, consumer)

    return Totals(
        health_cpu_s=delta("cobot_hmi_health_cpu_seconds_total"),
        gaps=delta("cobot_hmi_frame_gaps_total"),
        health_dropped=delta("cobot_hmi_consumer_dropped_frames_total", "health"),
    )


async def _login(http: httpx.AsyncClient, base_url: str) -> str:
    answer = await http.post(
        base_url + "/api/v1/auth/login",
        json={"username": BENCH_USER[0], "password": BENCH_USER[1]},
    )
    answer.raise_for_status()
    token: str = answer.json()["token"]
    return token


async def _set_baselines(running: Stack, cycles: int) -> None:
    """Every robot learns a baseline from its next ``cycles`` cycles (once per run)."""
    async with httpx.AsyncClient(timeout=30) as http:
        token = await _login(http, running.base_url)
        for name in running.robot_names:
            answer = await http.post(
                f"{running.base_url}/api/v1/robots/{name}/health/baselines",
                json={"reason": "bench/health: the demo program", "cycles": cycles},
                headers={"Authorization": f"Bearer {token}"},
            )
            answer.raise_for_status()


async def _phase(running: Stack, args: argparse.Namespace) -> tuple[Phase, Totals]:
    loop = asyncio.get_running_loop()
    await asyncio.sleep(args.settle_seconds)
    before = metrics((await loop.run_in_executor(None, running.get, "/metrics")).decode())
    phase = await measure(running, args.seconds)
    after = metrics((await loop.run_in_executor(None, running.get, "/metrics")).decode())
    return phase, _totals(before, after)


def _health_line(running: Stack, name: str) -> str:
    report = orjson.loads(running.get(f"/api/v1/robots/{name}/health"))
    baseline = report.get("baseline")
    learning = report.get("learning")
    if baseline is not None:
        state = "baseline learned"
    elif learning is not None:
        state = f"learning ({learning.get('cycles', '?')} cycles so far)"
    else:
        state = "no baseline"
    return f"{name}: {state}, verdict {report.get('verdict')}"


async def run(args: argparse.Namespace, state: Path) -> dict[str, Condition]:
    conditions = {"off": Condition(), "on": Condition()}
    emulator_args = ("--cycle-marker-register", str(CYCLE_MARKER_REGISTER))
    given_baselines = False
    with emulated_cell(
        args.robots, state, robot_niceness=args.robot_niceness, emulator_args=emulator_args
    ) as cell:
        for cycle in range(args.cycles):
            for condition in ("off", "on"):
                switch = ("--no-health-enabled",) if condition == "off" else ()
                log = f"service-{condition}-{cycle + 1}.log"
                service_args = ("--cycle-trigger", CYCLE_TRIGGER, *switch)
                with serving(cell, args.rpi_ms, *service_args, log=log) as running:
                    if condition == "on" and not given_baselines:
                        await _set_baselines(running, args.baseline_cycles)
                        given_baselines = True
                    phase, totals = await _phase(running, args)
                    conditions[condition].add(phase, totals)
                    if condition == "on" and cycle == args.cycles - 1:
                        for name in running.robot_names:
                            print("  health of " + _health_line(running, name))
                print(f"  cycle {cycle + 1}, health {condition}: {args.seconds:.0f} s measured")
    return conditions


def _worst_ratio(off: Phase, on: Phase) -> tuple[float, str]:
    worst, worst_name = 0.0, ""
    for name, robot_on in on.robots.items():
        p99_on, _ = histogram_quantile({}, robot_on.buckets, HISTOGRAM, 0.99)
        p99_off, _ = histogram_quantile({}, off.robots[name].buckets, HISTOGRAM, 0.99)
        ratio = p99_on / p99_off if p99_off > 0 else float("inf")
        print(f"    {name}: p99 {p99_off * 1e3:.3f} ms off, {p99_on * 1e3:.3f} ms on: {ratio:.3f}")
        if ratio > worst:
            worst, worst_name = ratio, name
    return worst, worst_name


def report(args: argparse.Namespace, conditions: dict[str, Condition]) -> bool:
    off, on = conditions["off"], conditions["on"]
    assert off.phase is not None and on.phase is not None
    frames_on = max(on.phase.frames_produced, 1)
    health_us = 1e6 * on.totals.health_cpu_s / frames_on
    service_on, service_off = on.phase.service_us_per_frame(), off.phase.service_us_per_frame()
    print(f"bench/health: {args.robots} robots at RPI {args.rpi_ms:g} ms, {args.cycles} cycles")
    print("  cyclic receive interval p99, health on over off, per robot:")
    worst, worst_name = _worst_ratio(off.phase, on.phase)
    gaps = on.totals.gaps + off.totals.gaps
    print(
        f"  health thread CPU per robot-frame: {health_us:.2f} µs "
        f"({on.totals.health_cpu_s:.2f} s over {on.phase.frames_produced} frames; "
        f"target ≤ {TARGET_HEALTH_US:g} µs)"
    )
    print(
        f"  service CPU per robot-frame: health on {service_on:.1f} µs, off {service_off:.1f} µs "
        f"(difference {service_on - service_off:+.1f} µs; the baseline of this run)"
    )
    print(
        f"  worst cyclic p99 ratio {worst:.3f} ({worst_name}; target ≤ {TARGET_RATIO}), "
        f"T→O gaps {gaps:.0f} (on {on.totals.gaps:.0f}, off {off.totals.gaps:.0f}), "
        f"frames health's queue dropped {on.totals.health_dropped:.0f}"
    )
    met = health_us <= TARGET_HEALTH_US and worst <= TARGET_RATIO and gaps == 0
    print(
        f"  targets met: {met}  ({os.cpu_count()} CPUs, load average "
        f"{os.getloadavg()[0]:.2f} at the end)"
    )
    return met


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=16)
    parser.add_argument("--rpi-ms", type=float, default=10.0)
    parser.add_argument("--seconds", type=float, default=60.0, help="measured per phase")
    parser.add_argument("--settle-seconds", type=float, default=5.0, help="after each start")
    parser.add_argument("--cycles", type=int, default=2, help="off/on alternations")
    parser.add_argument(
        "--baseline-cycles", type=int, default=3, help="each robot's cycles its baseline learns"
    )
    parser.add_argument(
        "--robot-niceness",
        type=int,
        default=-10,
        help="nice value of the emulators (a real robot is its own machine; 0: same as the rest)",
    )
    return parser.parse_args()


def main() -> int:
    args = _arguments()
    with tempfile.TemporaryDirectory(prefix="cobot-bench-health-") as directory:
        conditions = asyncio.run(run(args, Path(directory)))
    return 0 if report(args, conditions) else 1


if __name__ == "__main__":
    raise SystemExit(main())
