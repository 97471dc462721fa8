"""Layer: health (pure). Imports the other ``health`` modules' pure parts.

A robot's healthy reference, learned from frames the operator names (the next N cycles, or
until a time) and kept with the arm model and layout version it was learned on. Re-baselining
starts a new one with a reason and who asked; the engine keeps the old ones (their reasons and
dates, not their cells) so a trend can span them.
"""

from __future__ import annotations

import numpy as np

from cobot_hmi.health.frames import FloatArray, FrameBlock
from cobot_hmi.health.friction import CellTable, friction_per_speed
from cobot_hmi.health.health_settings import HealthSettings
from cobot_hmi.health.heat import HeatFit, cycle_heat
from cobot_hmi.health.signature import quantiles, resample


class Baseline:
    """One baseline: its record (``info``) and what it learned (see the module docstring)."""

    def __init__(self, settings: HealthSettings, joints: int, info: dict[str, object]) -> None:
        self.settings = settings
        self.info = info
        """id, reason, by, arm, layout_version, started_s, finished_s, target_cycles, until_s."""
        self.cells = CellTable(settings)
        self.steady_cells = CellTable(settings)
        """Steady-speed samples only: where the friction per °/s is measured."""
        self.signature_sum: FloatArray = np.zeros((settings.signature_points, joints))
        self.distribution_sum: FloatArray = np.zeros((101, joints))
        self.heat = HeatFit(joints)
        self.durations = np.zeros(3)  # n, Σd, Σd²
        self._per_speed: tuple[FloatArray, FloatArray] | None = None
        """Friction per °/s from the steady cells and from every cell, once measured: the
        cells change only while the baseline learns, a report asks for it every time."""

    @property
    def cycles(self) -> int:
        return int(self.durations[0])

    @property
    def finished(self) -> bool:
        return self.info.get("finished_s") is not None

    def add_frames(self, block: FrameBlock, acceleration_deg_s2: FloatArray) -> None:
        """Distinct samples and their accelerations (``health.samples``)."""
        self.cells.add(block, acceleration_deg_s2)
        self.steady_cells.add(block, acceleration_deg_s2, steady_only=True)
        self._per_speed = None

    def add_cycle(self, block: FrameBlock, start_s: float, end_s: float) -> None:
        points = self.settings.signature_points
        self.signature_sum += resample(block, start_s, end_s, points)
        self.distribution_sum += quantiles(block)
        self.heat.add(*cycle_heat(block, self.settings.thermal_time_constant_s))
        d = end_s - start_s
        self.durations += (1.0, d, d * d)

    def friction_per_speed(self, joints: int) -> FloatArray:
        """Per joint: its friction per °/s (N·m s/°) as this baseline measured it: at steady
        speeds where it saw enough of them both ways (inertia plays no part), else from every
        sample's fit."""
        steady, fitted = self._friction_per_speed(joints)
        return np.where(np.isfinite(steady), steady, fitted)

    def friction_reference(self, joints: int) -> list[str | None]:
        """Per joint, where its friction per °/s comes from: ``"steady"`` (cells seen both
        ways at steady speed), ``"fitted"`` (every cell seen both ways, accelerating too: rougher,
        docs/health.md), ``None`` (no reference: no friction figure)."""
        steady, fitted = self._friction_per_speed(joints)
        return [
            "steady" if np.isfinite(a) else "fitted" if np.isfinite(b) else None
            for a, b in zip(steady, fitted, strict=True)
        ]

    def _friction_per_speed(self, joints: int) -> tuple[FloatArray, FloatArray]:
        if self._per_speed is None or self._per_speed[0].size != joints:
            self._per_speed = (
                friction_per_speed(self.steady_cells, joints, self.settings),
                friction_per_speed(self.cells, joints, self.settings),
            )
        return self._per_speed

    def due(self, now_s: float) -> bool:
        """Learned enough: the cycles asked for, or the period's end passed."""
        target = self.info.get("target_cycles")
        until = self.info.get("until_s")
        if isinstance(target, int) and self.cycles >= target:
            return True
        return isinstance(until, int | float) and now_s >= until and self.cycles > 0

    @property
    def signature(self) -> FloatArray:
        return self.signature_sum / max(self.cycles, 1)

    @property
    def distribution(self) -> FloatArray:
        return self.distribution_sum / max(self.cycles, 1)

    def cycle_time(self) -> tuple[float, float]:
        n, total, squares = self.durations
        mean = total / n
        variance = max(squares / n - mean * mean, 0.0)
        return mean, float(np.sqrt(variance))

    def to_state(self) -> dict[str, object]:
        return {
            "info": self.info,
            "cells": self.cells.to_state(),
            "steady_cells": self.steady_cells.to_state(),
            "signature_sum": self.signature_sum.tolist(),
            "distribution_sum": self.distribution_sum.tolist(),
            "heat_sums": self.heat.sums.tolist(),
            "durations": self.durations.tolist(),
        }

    @classmethod
    def from_state(
        cls, settings: HealthSettings, joints: int, state: dict[str, object]
    ) -> Baseline:
        info = state["info"]
        assert isinstance(info, dict)
        baseline = cls(settings, joints, dict(info))
        cells = state["cells"]
        assert isinstance(cells, dict)
        baseline.cells = CellTable.from_state(settings, cells)
        steady = state["steady_cells"]
        assert isinstance(steady, dict)
        baseline.steady_cells = CellTable.from_state(settings, steady)
        baseline.signature_sum = np.array(state["signature_sum"], dtype=np.float64)
        baseline.distribution_sum = np.array(state["distribution_sum"], dtype=np.float64)
        baseline.heat.sums = np.array(state["heat_sums"], dtype=np.float64)
        baseline.durations = np.array(state["durations"], dtype=np.float64)
        return baseline
