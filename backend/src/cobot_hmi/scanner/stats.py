"""Layer: scanner. Imports nothing of the project.

Interval statistics over a recent window of received frames: mean, p99, max in milliseconds.
Appending is O(1); the figures are computed only when asked.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass


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

    def add(self, interval_ms: float) -> None:
        self._intervals_ms.append(interval_ms)

    def clear(self) -> None:
        self._intervals_ms.clear()

    def figures(self) -> IntervalFigures:
        values = sorted(self._intervals_ms)
        if not values:
            return IntervalFigures(0, None, None, None, None)
        n = len(values)
        return IntervalFigures(
            n,
            sum(values) / n,
            values[min(n - 1, n // 2)],
            values[min(n - 1, int(n * 0.99))],
            values[-1],
        )
