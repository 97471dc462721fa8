"""``bench/history --memory``: the recorder's memory across segment closes of a robot at RPI 2 ms.

Records simulated time as fast as it goes through the recorder's own path (hub items → record
batches of a second → the journal; every 10 minutes the journal handed to the closer,
``history.closer``, which turns it into Parquet and cells in a process of its own,
``history.close_process``). Prints the process's RSS (anonymous + file-backed, as ``ps`` and
the soak read it) before each close, its peak while the closer works (sampled every 2 ms) and
after, and the drift from simulated minute 5 to the end against the soak's target (±5 %). Each
in a fresh process with glibc's malloc arenas limited as ``cobot-hmi`` limits them
(cli/process_memory.py): first as the closer works now, then, as the baseline of the same run,
with each journal closed in the recording process (on the closer's thread, the Parquet writer
loaded before the first close, Arrow's and glibc's freed memory handed back after each), as it
was before.
"""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pyarrow as pa
from proc_stats import rss_mib

from cobot_hmi.cli.process_memory import limit_malloc_arenas
from cobot_hmi.codec import decode_frame, encode_frame
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.history import segments
from cobot_hmi.history.close_process import close_in_child
from cobot_hmi.history.closer import JournalCloser
from cobot_hmi.history.journal_form import records_to_journal_batch
from cobot_hmi.history.segments import Segment

RATE_HZ = 500
"""RPI 2 ms."""
SEGMENT_S = 600.0
START_S = 1_900_000_000.0
TARGET_DRIFT = 0.05


class PeakSampler:
    """RSS sampled every 2 ms on a thread: the highest since ``reset``."""

    def __init__(self) -> None:
        self.peak = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def reset(self) -> None:
        self.peak = rss_mib()

    def _run(self) -> None:
        while not self._stop.wait(0.002):
            self.peak = max(self.peak, rss_mib())

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def measure(closes: int, root: Path, convert: Callable[[Path, str], Segment | None]) -> None:
    """Record until ``closes`` segments closed; print the figures."""
    robot = SimulatedRobot(RobotSettings(), start_s=START_S - 5)
    payloads = [
        encode_frame(robot.produce_frame(START_S + i / RATE_HZ)) for i in range(RATE_HZ * 10)
    ]
    pool = [(decode_frame(payload), payload) for payload in payloads]
    simulated_now = [START_S]
    writer = segments.SegmentWriter(root, "r", SEGMENT_S, clock=lambda: simulated_now[0])
    closer = JournalCloser(retry_s=5.0, convert=convert)
    closer.start()
    sampler = PeakSampler()
    minute_5: float | None = None
    after_each: list[float] = []
    print(f"  start: RSS {rss_mib():.1f} MiB")
    seq = second = 0
    closing: tuple[float, float] | None = None
    """RSS before the hand-over and its time, while the closer works."""
    try:
        while len(after_each) < closes:
            items = []
            for i in range(RATE_HZ):
                seq += 1
                frame, payload = pool[seq % len(pool)]
                items.append((seq, START_S + second + i / RATE_HZ, frame, seq, payload))
            writer.append(records_to_journal_batch(items))  # as the recorder appends
            second += 1
            simulated_now[0] = START_S + second
            if second == 300:
                minute_5 = rss_mib()
            if closing is not None and closer.pending == 0:
                before, started = closing
                closing = None
                took = time.perf_counter() - started
                after = rss_mib()
                after_each.append(after)
                print(f"  close {len(after_each)}: RSS before {before:.1f} MiB, peak "
                      f"{sampler.peak:.1f} (+{sampler.peak - before:.1f}), after {after:.1f} "
                      f"({after - before:+.1f}); {took:.1f} s while recording on")  # fmt: skip
                for segment in segments.list_segments(root, "r"):  # the disk stays small
                    segment.path.unlink()
                    segment.rollup_path.unlink()
            if not writer.due():
                continue
            if closing is not None and closer.pending:
                # Ten simulated minutes go by faster than a close: a live recorder has ten
                # real minutes, so the next journal is handed over once this one is closed.
                while closer.pending:
                    time.sleep(0.01)
                continue
            before = rss_mib()
            path = writer.finish_journal()
            assert path is not None
            sampler.reset()
            closing = (before, time.perf_counter())
            closer.submit("r", path)
    finally:
        sampler.stop()
        closer.stop()
    if minute_5 is not None:
        low, high = min(after_each), max(after_each)
        drift = max(abs(low - minute_5), abs(high - minute_5)) / minute_5
        verdict = "OK" if drift <= TARGET_DRIFT else "MISSED"
        print(f"  RSS at minute 5 {minute_5:.1f} MiB, after the closes {low:.1f} … {high:.1f}: "
              f"{drift * 100:.1f} % (target ±{TARGET_DRIFT * 100:.0f} %) {verdict}")  # fmt: skip


def close_here(path: Path, robot: str) -> Segment | None:
    """The baseline's closing: in this process (the way before), what it freed handed back."""
    try:
        return segments.close_journal(path, robot)
    finally:
        pa.default_memory_pool().release_unused()
        ctypes.CDLL(None).malloc_trim(0)


def load_writers_here(root: Path) -> None:
    """The baseline's start: a one-frame journal closed here, so the Parquet writer's code and
    tables (about 20 MiB for the process's life) are in memory before minute 5, as the closer's
    thread loaded them before."""
    robot = SimulatedRobot(RobotSettings(), start_s=START_S - 5)
    payload = encode_frame(robot.produce_frame(START_S - 1))
    writer = segments.SegmentWriter(root, "warm-up", SEGMENT_S)
    writer.append(records_to_journal_batch([(1, START_S - 1, decode_frame(payload), 1, payload)]))
    path = writer.finish_journal()
    assert path is not None
    close_here(path, "warm-up")


def measure_in_fresh_process(closes: int, closing: str) -> None:
    """``measure`` in a fresh Python, journals closed as ``closing`` says: "child" (the closer's
    process per journal) or "here" (the baseline: in the recording process)."""
    subprocess.run([sys.executable, __file__, closing, str(closes)], check=True)


def main(closes: int) -> int:
    print(f"load average before: {os.getloadavg()}")
    for closing, title in (
        ("child", "as cobot-hmi records (each journal closed in a process of its own)"),
        ("here", "baseline: each journal closed in the recording process, as before"),
    ):
        print(f"\nmemory, {title}: a robot at RPI 2 ms ({RATE_HZ} frames/s), {closes} segments "
              f"of {SEGMENT_S / 60:.0f} minutes closed while recording:", flush=True)  # fmt: skip
        measure_in_fresh_process(closes, closing)
    print(f"\nload average after: {os.getloadavg()}")
    return 0


def child(closing: str, closes: int) -> int:
    """One measurement (in the process ``measure_in_fresh_process`` started)."""
    assert limit_malloc_arenas(), "this C library takes no M_ARENA_MAX"
    with tempfile.TemporaryDirectory(prefix="cobot-history-memory-") as directory:
        if closing == "here":
            load_writers_here(Path(directory))
        measure(closes, Path(directory), close_here if closing == "here" else close_in_child)
    return 0


if __name__ == "__main__":
    sys.exit(child(sys.argv[1], int(sys.argv[2])))
