"""Layer: emulator, pure robot model (no I/O). Imports nothing of the project.

Measurement noise for the monitoring values, cheap enough for every produced frame.

A frame carries about twenty noisy values (motor currents, external torques, force, moment, analog
inputs). Drawing each from ``random.gauss`` costs a Python-level Box-Muller step per value, a
good share of the whole frame at a 2 ms RPI. Instead, ``GaussianNoise`` draws a table of standard
normal values once from the seeded generator, and each request takes a run of it from a random
offset (one call to the generator), already scaled: every value is still a standard normal draw,
successive frames use independent offsets, and the same seed gives the same noise.
"""

from __future__ import annotations

import random
from typing import Final

TABLE_SIZE: Final = 4096
"""Standard normal draws kept (a few milliseconds to draw once per robot)."""


class GaussianNoise:
    """Zero-mean Gaussian noise of any standard deviation, drawn from a seeded generator."""

    def __init__(self, rng: random.Random, size: int = TABLE_SIZE) -> None:
        self._random = rng.random
        self._size = size
        self._unit = [rng.gauss(0.0, 1.0) for _ in range(size)]
        self._scaled: dict[float, tuple[float, ...]] = {}
        """Tables as tuples: a slice of one is already the tuple ``take`` returns."""

    def take(self, count: int, sigma: float) -> tuple[float, ...]:
        """``count`` values of standard deviation ``sigma``."""
        table = self._scaled.get(sigma)
        if table is None:
            table = self._scaled[sigma] = tuple([z * sigma for z in self._unit])
        start = int(self._random() * (self._size - count))
        return table[start : start + count]
