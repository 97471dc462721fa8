"""Layer: health (pure). Imports ``health.frames``.

Reducer life used: the strain-wave and cycloidal reducer makers' life law,
``L = L_rated · (ω_rated/ω)·(τ_rated/τ)^(10/3)``, summed over the load as it comes:
``Σ (|ω|/ω_rated)·(|τ|/τ_rated)^(10/3)·dt`` is the time the joint has aged, in hours at its
rated load; against the rated life that is the life used. The rate of the last seven days
(aged hours per hour of the clock) gives the remaining life at this week's duty.
"""

from __future__ import annotations

import numpy as np

from cobot_hmi.health.frames import FloatArray, FrameBlock

LIFE_EXPONENT = 10.0 / 3.0
MAX_STEP_S = 1.0
"""A longer gap between frames (the link lost, the service stopped) counts as this long."""
_DAY_S = 86_400.0
_WEEK_DAYS = 7


class LifeMeter:
    """Aged hours per joint and per day (for this week's duty)."""

    def __init__(self, rated_torque_nm: FloatArray, rated_speed_deg_s: FloatArray) -> None:
        self.rated_torque_nm = rated_torque_nm
        self.rated_speed_deg_s = rated_speed_deg_s
        self.aged_h: FloatArray = np.zeros_like(rated_torque_nm)
        self.days: dict[int, list[float]] = {}
        """Day number → [clock hours covered, aged hours per joint...]."""
        self.last_time_s: float | None = None

    def add(self, block: FrameBlock) -> None:
        if len(block) == 0:
            return
        times = block.time_s
        previous = times[0] if self.last_time_s is None else self.last_time_s
        # np.diff(prepend=) and np.clip, written out: the same steps at a third of the calls'
        # overhead, which is most of their cost in a second's block.
        steps = np.empty_like(times)
        steps[0] = times[0] - previous
        np.subtract(times[1:], times[:-1], out=steps[1:])
        np.maximum(steps, 0.0, out=steps)
        np.minimum(steps, MAX_STEP_S, out=steps)
        load = (np.abs(block.velocity_deg_s) / self.rated_speed_deg_s) * (
            np.abs(block.torque_nm) / self.rated_torque_nm
        ) ** LIFE_EXPONENT
        aged_h = (load * steps[:, None]).sum(axis=0) / 3600.0
        self.aged_h = self.aged_h + aged_h
        day = int(times[-1] // _DAY_S)
        bucket = self.days.setdefault(day, [0.0] * (1 + aged_h.size))
        bucket[0] += float(steps.sum()) / 3600.0
        for j, value in enumerate(aged_h):
            bucket[1 + j] += float(value)
        for old in [d for d in self.days if d <= day - _WEEK_DAYS]:
            del self.days[old]
        self.last_time_s = float(times[-1])

    def week_rate(self) -> FloatArray:
        """Aged hours per clock hour over the last seven days."""
        if not self.days:
            return np.zeros_like(self.aged_h)
        rows = np.array(list(self.days.values()))
        clock_h = rows[:, 0].sum()
        return rows[:, 1:].sum(axis=0) / clock_h if clock_h > 0 else np.zeros_like(self.aged_h)

    def to_state(self) -> dict[str, object]:
        return {
            "aged_h": self.aged_h.tolist(),
            "days": {str(day): values for day, values in self.days.items()},
            "last_time_s": self.last_time_s,
        }

    def restore(self, state: dict[str, object]) -> None:
        self.aged_h = np.array(state["aged_h"], dtype=np.float64)
        days = state["days"]
        assert isinstance(days, dict)
        self.days = {int(day): [float(v) for v in values] for day, values in days.items()}
        last = state["last_time_s"]
        self.last_time_s = None if last is None else float(last)  # type: ignore[arg-type]
