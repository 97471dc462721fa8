"""Alarm engine benchmark (see bench/alarms). Prints figures and the target they are held
against.

Target (issue 13: "cheap"): evaluating a robot's alarms on a frame where nothing changes costs
less than decoding that frame (the codec's ``decode_frame``, paid for every frame already), at
1 ms RPI a small share of a core. Every figure is the median of rounds in which the works take
turns, so a change of the machine's load falls on all of them alike.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "backend" / "tests"))

from cobot_hmi.codec import decode_frame
from cobot_hmi.service.alarms.engine import AlarmEngine, UserAlarm
from cobot_hmi.service.events.text import FrameWatcher
from golden_vectors import t2o_vectors

ROUNDS = 5
TARGET_RATIO_TO_DECODE = 1.0


def interleaved_us(works: dict[str, Callable[[], None]], calls: int) -> dict[str, list[float]]:
    samples: dict[str, list[float]] = {name: [] for name in works}
    for _ in range(ROUNDS):
        for name, work in works.items():
            start = time.perf_counter()
            work()
            samples[name].append((time.perf_counter() - start) / calls * 1e6)
    return samples


def main() -> int:
    frames = int(sys.argv[1]) if len(sys.argv) > 1 else 200_000
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    wire = t2o_vectors()[1].wire  # the realistic mid-motion frame
    frame = decode_frame(wire)
    currents = [
        UserAlarm(name=f"current-{i}", field="joint_motor_current", index=i, high=1e6, low=-1e6)
        for i in range(6)
    ]
    users = (
        *currents,
        UserAlarm(
            name="di-3", field="controlbox_di", index=2, active_when=not frame.controlbox_di[2]
        ),
        UserAlarm(name="force-z", field="external_force", index=2, high=1e6, deadband=1.0),
    )
    engine = AlarmEngine(
        "bench",
        motor_temperature_c=1e6,
        motor_temperature_deadband_c=2.0,
        gap_rate_per_min=10.0,
        connection_delay_s=2.0,
        shelve_max_s=60.0,
        user_alarms=users,
    )
    engine.observe(frame, 0.0)  # the frame's own state: from now on nothing changes
    watcher = FrameWatcher()
    watcher.observe(frame, 0.0)
    loop = range(frames)
    observe, watch = engine.observe, watcher.observe

    def decode() -> None:
        for _ in loop:
            decode_frame(wire)

    def alarms() -> None:
        for _ in loop:
            observe(frame, 1.0)

    def events() -> None:
        for _ in loop:
            watch(frame, 1.0)

    samples = interleaved_us({"decode": decode, "alarms": alarms, "events": events}, frames)
    decode_us, alarms_us, events_us = (
        statistics.median(samples[name]) for name in ("decode", "alarms", "events")
    )
    ratio = statistics.median(
        a / d for a, d in zip(samples["alarms"], samples["decode"], strict=True)
    )
    checks = len(engine.alarms) - 3  # the connection and packet loss alarms are not per frame
    print(
        f"alarm engine: {len(engine.alarms)} alarms, {checks} evaluated per frame, {frames} frames"
    )
    print(f"  decode_frame           {decode_us:7.3f} µs/frame (the baseline)")
    print(f"  alarms, no change      {alarms_us:7.3f} µs/frame  ({ratio:.2f}x decode)")
    print(f"  event watcher          {events_us:7.3f} µs/frame")
    print(f"  at 1 ms RPI: {alarms_us / 10:.2f} % of a core per robot for the alarms")
    ok = ratio < TARGET_RATIO_TO_DECODE
    print(f"target: alarms < {TARGET_RATIO_TO_DECODE:g}x decode: {'met' if ok else 'NOT met'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
