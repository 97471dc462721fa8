"""Layer: service. One robot's T→O receive intervals and frame counts, for ``/metrics``.

A frame consumer (``robots.frame_notifier``) on the web loop: it counts the frames it was handed and
the ones its queue lost, and sorts every receive interval (kernel receive time to kernel
receive time) into a histogram whose buckets are fine near the RPI (0.25 ms up to 30 ms).
After a reconnect the first interval means nothing: ``reset_baseline`` forgets the last time.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from typing import Final

from cobot_hmi.service.robots.frame_notifier import FrameRecord, Runs

QUEUE_FRAMES: Final = 4096
"""Frames the loop may fall behind by before the oldest are lost (~40 s at 10 ms)."""

INTERVAL_BUCKETS_S: Final = (
    *(i / 4000 for i in range(120)),  # 0 … 29.75 ms in 0.25 ms steps: p99 near the RPI
    *(i / 1000 for i in (30, 40, 50, 75, 100, 250, 500, 1000)),
)
"""Upper bounds of the receive-interval histogram, seconds."""


class ReceiveIntervals:
    """Counts and the interval histogram of one robot (see the module docstring)."""

    name: Final = "receive-intervals"
    runs: Final = Runs.LOOP
    queue_frames: Final = QUEUE_FRAMES

    def __init__(self) -> None:
        self.frames_in = 0
        self.frames_lost = 0
        """Frames published that this consumer never saw (the loop fell a queue behind)."""
        self.buckets = [0] * (len(INTERVAL_BUCKETS_S) + 1)
        self.sum_s = 0.0
        self.count = 0
        self._last_seq = 0
        self._last_t: float | None = None

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        first_seq = records[0].seq
        if self._last_seq and first_seq > self._last_seq + 1:
            self.frames_lost += first_seq - self._last_seq - 1
        self._last_seq = records[-1].seq
        self.frames_in += len(records)
        previous = self._last_t
        buckets = self.buckets
        for record in records:
            t = record.received_at_s
            if previous is not None:
                interval_s = t - previous
                self.sum_s += interval_s
                self.count += 1
                buckets[bisect.bisect_left(INTERVAL_BUCKETS_S, interval_s)] += 1
            previous = t
        self._last_t = previous

    def reset_baseline(self) -> None:
        self._last_t = None

    def histogram(self) -> list[tuple[float, int]]:
        """Cumulative (upper bound s, count) pairs, ``inf`` last, for Prometheus."""
        out = []
        running = 0
        for bound, count in zip((*INTERVAL_BUCKETS_S, float("inf")), self.buckets, strict=True):
            running += count
            out.append((bound, running))
        return out
