"""Layer: health (pure). Imports ``health.frames``.

Heat: each motor's temperature against what its current explains. A motor heats first-order,
``τ·dT/dt + T = a + b·I²``; averaged over a cycle this is exact:
``T_mean + τ·(T_end − T_start)/D = a + b·mean(I²)``, so each cycle gives the temperature the
motor is heading for (``settled``) even while it warms from a cold start. The baseline fits
``a`` and ``b`` per joint over its cycles (least squares; ``b = 0`` when the duty never
varied); afterwards each cycle's excess ``settled − (a + b·mean(I²))`` is smoothed over a few
cycles, and the median excess of the six joints (a warmer room, which warms them all) is taken
off, so a motor hot for its duty stands out from one that merely works hard.
"""

from __future__ import annotations

import numpy as np

from cobot_hmi.health.frames import FloatArray, FrameBlock


def cycle_heat(block: FrameBlock, time_constant_s: float) -> tuple[FloatArray, FloatArray]:
    """Per joint: the cycle's mean I² (A²) and the temperature it heads for (°C)."""
    duration_s = float(block.time_s[-1] - block.time_s[0])
    temperature = block.temperature_c
    slope = (temperature[-1] - temperature[0]) / duration_s if duration_s > 0 else 0.0
    settled = temperature.mean(axis=0) + time_constant_s * slope
    return np.mean(block.current_a**2, axis=0), settled


class HeatFit:
    """Least-squares sums of ``settled = a + b·I²`` per joint, and the fit."""

    def __init__(self, joints: int) -> None:
        self.sums = np.zeros((5, joints))  # n, Σx, Σy, Σxx, Σxy

    def add(self, current_sq: FloatArray, settled: FloatArray) -> None:
        self.sums += np.stack(
            [np.ones_like(settled), current_sq, settled, current_sq**2, current_sq * settled]
        )

    def coefficients(self) -> tuple[FloatArray, FloatArray]:
        n, sx, sy, sxx, sxy = self.sums
        n = np.where(n > 0, n, 1.0)
        variance = sxx / n - (sx / n) ** 2
        spread = np.maximum(variance, 0.0) > 1e-6 * np.maximum((sx / n) ** 2, 1e-9)
        safe = np.where(spread, variance, 1.0)
        slope = np.where(spread, (sxy / n - sx * sy / n**2) / safe, 0.0)
        return sy / n - slope * sx / n, slope


class HeatMonitor:
    """The smoothed excess per joint after the baseline."""

    def __init__(self, joints: int) -> None:
        self.excess_c: FloatArray = np.full(joints, np.nan)

    def add(self, excess_c: FloatArray, memory_cycles: float) -> None:
        alpha = 1.0 / max(memory_cycles, 1.0)
        first = np.isnan(self.excess_c)
        self.excess_c = np.where(
            first, excess_c, self.excess_c + alpha * (excess_c - self.excess_c)
        )

    def relative_c(self) -> FloatArray:
        """The excess with the joints' median (the room) taken off."""
        if np.all(np.isnan(self.excess_c)):
            return self.excess_c
        return self.excess_c - float(np.nanmedian(self.excess_c))
