"""The health engine alone (``bench/health --engine-only``, issue 40): what one robot-frame costs
the health thread, in process, without the service around it.

The emulated arm (``SimulatedRobot``: the demo program with its cycle marker, monitoring values
refreshed every 100 ms as the real controller's) is stepped once at 100 Hz for ``--seconds`` and
its frames kept; then each of ``--robots`` engines is fed them as the service's health thread
feeds it (``service/health/monitor.py``): the frames appended one by one as they are delivered,
a block every ``health_refresh_s`` (``FrameBlock.from_frames``, ``observe``), the cycles ended
at the marker's rising edges once their frames are in, a baseline learned from the cycles after
the first three, a report every 30 s (``health_report_s``). Timed with the process's CPU clock,
best of ``--rounds``, split into the block's conversion, the engine and the reports; beside the
conversion, what ``FrameBlock.from_payloads`` costs the same blocks from their raw bytes.

Beside it, two references on the same frames and the same clock: decoding each frame from its
284 bytes (``decode_frame``: what the scanner pays once per frame for every consumer) and a
bare copy of the frames' joint values into arrays (``np.array`` of the frames: the least a
block costs). The load average is printed: on a shared machine every figure moves with it.
Target (``bench/health``): ≤ 15 µs of health CPU per robot-frame, measured there in the
service; this mode says how much of it the engine is.
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from cobot_hmi.arms import M1013_ARM
from cobot_hmi.codec import Frame, decode_frame, encode_frame
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.health import FrameBlock, HealthEngine
from cobot_hmi.service.health.health_service_settings import HealthServiceSettings

MARKER_REGISTER = 63
RATE_HZ = 100
BLOCK_FRAMES = int(HealthServiceSettings().health_refresh_s * RATE_HZ)  # as the service feeds it
REPORT_EVERY_BLOCKS = 30  # health_report_s = 30 s
BASELINE_AFTER_CYCLES = 3
BASELINE_CYCLES = 20
TARGET_HEALTH_US = 15.0


@dataclass
class Split:
    """CPU seconds of one feed, by part."""

    convert_s: float = 0.0
    engine_s: float = 0.0
    report_s: float = 0.0
    frames: int = 0
    cycles: int = 0
    reports: int = 0
    baseline: list[bool] = field(default_factory=list)

    @property
    def total_s(self) -> float:
        return self.convert_s + self.engine_s + self.report_s


def produce(seconds: float) -> tuple[list[float], list[Frame]]:
    robot = SimulatedRobot(
        RobotSettings(cycle_marker_register=MARKER_REGISTER, kinematic_refresh_ms=100.0),
        start_s=0.0,
    )
    times = [k / RATE_HZ for k in range(int(seconds * RATE_HZ))]
    return times, [robot.produce_frame(t) for t in times]


def cycle_edges(times: Sequence[float], frames: Sequence[Frame]) -> list[tuple[float, float]]:
    """The cycles between the marker's rising edges (the service's cycle meter's)."""
    edges, marker = [], True
    for t, frame in zip(times, frames, strict=True):
        now = frame.bit_output_registers[MARKER_REGISTER]
        if now and not marker:
            edges.append(t)
        marker = now
    return list(itertools.pairwise(edges))


def feed(times: Sequence[float], frames: Sequence[Frame], split: Split) -> None:
    """One robot's engine fed as the service feeds it (see the module docstring)."""
    clock = time.process_time
    engine = HealthEngine(M1013_ARM)
    cycles = cycle_edges(times, frames)
    pending_t: list[float] = []
    pending_f: list[Frame] = []
    for block_no, first in enumerate(range(0, len(frames), BLOCK_FRAMES), start=1):
        t0 = clock()
        for k in range(first, min(first + BLOCK_FRAMES, len(frames))):
            pending_t.append(times[k])
            pending_f.append(frames[k])
        block = FrameBlock.from_frames(pending_t, pending_f)
        pending_t, pending_f = [], []
        t1 = clock()
        engine.observe(block)
        while cycles and cycles[0][1] <= engine.last_time_s:
            start_s, end_s = cycles.pop(0)
            engine.end_cycle(start_s, end_s)
            fresh = engine.learning is None and not engine.history
            if engine.cycles == BASELINE_AFTER_CYCLES and fresh:
                engine.begin_baseline("bench", "bench", end_s, cycles=BASELINE_CYCLES)
        t2 = clock()
        if block_no % REPORT_EVERY_BLOCKS == 0:
            engine.report()
            split.reports += 1
        t3 = clock()
        split.convert_s += t1 - t0
        split.engine_s += t2 - t1
        split.report_s += t3 - t2
    split.frames += len(frames)
    split.cycles += engine.cycles
    split.baseline.append(engine.baseline is not None)


def per_frame_us(action: Callable[[], object], frames: int, rounds: int) -> float:
    """The best of ``rounds`` runs of ``action``, in µs per frame."""
    best = float("inf")
    for _ in range(rounds):
        t0 = time.process_time()
        action()
        best = min(best, time.process_time() - t0)
    return 1e6 * best / frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--engine-only", action="store_true", help="(this mode; accepted)")
    parser.add_argument("--robots", type=int, default=4, help="engines fed the frames")
    parser.add_argument("--seconds", type=float, default=300.0, help="of frames per robot")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    t0 = time.monotonic()
    times, frames = produce(args.seconds)
    print(f"{len(frames)} frames of the emulated M1013 ({time.monotonic() - t0:.1f} s to step)")
    best: Split | None = None
    for _ in range(args.rounds):
        split = Split()
        for _ in range(args.robots):
            feed(times, frames, split)
        if best is None or split.total_s < best.total_s:
            best = split
    assert best is not None
    n = best.frames
    raws = [encode_frame(f) for f in frames]
    decode_us = per_frame_us(lambda: [decode_frame(r) for r in raws], len(raws), args.rounds)
    blocks = [
        (times[k : k + BLOCK_FRAMES], raws[k : k + BLOCK_FRAMES])
        for k in range(0, len(raws), BLOCK_FRAMES)
    ]
    from_payloads = getattr(FrameBlock, "from_payloads", None)  # absent in older trees
    payloads_us = (
        math.nan
        if from_payloads is None
        else per_frame_us(lambda: [from_payloads(t, r) for t, r in blocks], len(raws), args.rounds)
    )
    copy_us = per_frame_us(
        lambda: np.array([f.joint_torque for f in frames]), len(frames), args.rounds
    )
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} ({os.cpu_count()} cores)")
    print(
        f"{args.robots} robot(s) × {len(frames)} frames, {best.cycles} cycles judged or learned, "
        f"{best.reports} reports, baselines learned {sum(best.baseline)}/{args.robots}"
    )
    report_ms = 1e3 * best.report_s / max(best.reports, 1)
    rows = (
        ("health engine", best.total_s, f"target ≤ {TARGET_HEALTH_US:.0f} in the service"),
        ("  block conversion", best.convert_s, "append + FrameBlock.from_frames"),
        ("  engine", best.engine_s, "observe + end_cycle"),
        ("  reports", best.report_s, f"{report_ms:.2f} ms each"),
    )
    for name, seconds, note in rows:
        print(f"{name:<20}{1e6 * seconds / n:7.2f} µs/robot-frame ({note})")
    print(
        f"{'  from payloads':<20}{payloads_us:7.2f} µs/robot-frame "
        "(FrameBlock.from_payloads of the raw bytes, in place of the conversion)"
    )
    print(f"{'reference: decode':<20}{decode_us:7.2f} µs/frame (decode_frame of its 284 bytes)")
    print(f"{'reference: copy':<20}{copy_us:7.2f} µs/frame (np.array of one joint field)")


if __name__ == "__main__":
    main()
