"""Layer: scanner. Imports nothing of the project.

Interval statistics over a recent window of received frames: mean, p99, max in milliseconds.
Appending is O(1); the figures are computed only when asked.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class IntervalFigures:
    count: int
    mean_ms: float | None
    p50_ms: float | None
    p99_ms: float | None
    max_ms: float | None


class IntervalWindow:
    """The newest ``size`` receive intervals. ``add`` is a list's own append (one C call per
    frame on the cyclic thread); what was added is moved into a numpy ring when the figures
    are asked (or, unasked, once it fills a window: ``bound``), so each interval is converted
    once, not at every status message and scrape of every robot as the whole window was
    (copying a deque of 2048 Python floats into an array was most of ``figures``)."""

    def __init__(self, size: int = 2048) -> None:
        self._size = size
        self._ring = np.empty(size, dtype=np.float64)
        self._count = 0
        """Intervals in the ring (the first ``_count`` slots until it wraps)."""
        self._next = 0
        """The ring's slot for the next interval."""
        self._added: list[float] = []
        self.add: Callable[[float], None] = self._added.append
        """Add one interval (ms): the list's own append, no call of ours per frame."""

    def clear(self) -> None:
        self._added.clear()  # in place: ``add`` is bound to this list
        self._count = self._next = 0

    def bound(self) -> None:
        """Move what was added into the ring once it fills a window (the owner calls this once
        per batch of packets), so an owner nobody asks for figures holds no more than that."""
        if len(self._added) >= self._size:
            self._fold()

    def _fold(self) -> None:
        added = self._added
        if not added:
            return
        new = np.array(added[-self._size :], dtype=np.float64)
        added.clear()
        size, start, k = self._size, self._next, new.size
        first = min(k, size - start)
        self._ring[start : start + first] = new[:first]
        self._ring[: k - first] = new[first:]
        self._next = (start + k) % size
        self._count = min(size, self._count + k)

    def figures(self) -> IntervalFigures:
        """Mean, median, p99 (the value at rank ⌊0.99·n⌋ of the sorted window) and max. Read on
        the cyclic thread for every status message and scrape of every robot: numpy's partial
        sort (a third of ``sorted`` on the 2048 intervals), so each call holds the thread less."""
        self._fold()
        n = self._count
        if n == 0:
            return IntervalFigures(0, None, None, None, None)
        values = self._ring[:n]
        median_rank, p99_rank = min(n - 1, n // 2), min(n - 1, int(n * 0.99))
        ranked = np.partition(values, (median_rank, p99_rank))
        return IntervalFigures(
            n,
            float(values.mean()),
            float(ranked[median_rank]),
            float(ranked[p99_rank]),
            float(values.max()),
        )
