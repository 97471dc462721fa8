"""Layer: scanner. Imports nothing of the project.

Interval statistics over a recent window of received frames: mean, p99, max in milliseconds.
Appending is O(1); the figures are computed only when asked.
"""

from __future__ import annotations

from collections import deque
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
    def __init__(self, size: int = 2048) -> None:
        self._intervals_ms: deque[float] = deque(maxlen=size)
        self.add: Callable[[float], None] = self._intervals_ms.append
        """Add one interval (ms): the deque's own append, no call of ours per frame."""

    def clear(self) -> None:
        self._intervals_ms.clear()

    def figures(self) -> IntervalFigures:
        """Mean, median, p99 (the value at rank ⌊0.99·n⌋ of the sorted window) and max. Read on
        the cyclic thread for every status message and scrape of every robot: numpy's partial
        sort (a third of ``sorted`` on the 2048 intervals), so each call holds the thread less."""
        n = len(self._intervals_ms)
        if n == 0:
            return IntervalFigures(0, None, None, None, None)
        values = np.fromiter(self._intervals_ms, dtype=np.float64, count=n)
        median_rank, p99_rank = min(n - 1, n // 2), min(n - 1, int(n * 0.99))
        ranked = np.partition(values, (median_rank, p99_rank))
        return IntervalFigures(
            n,
            float(values.mean()),
            float(ranked[median_rank]),
            float(ranked[p99_rank]),
            float(values.max()),
        )
