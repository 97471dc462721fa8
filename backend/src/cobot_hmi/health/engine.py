"""Layer: health (pure). Imports the other ``health`` modules, ``arms`` and the layout.

``HealthEngine``: one robot's health, a consumer of its frames that never sits on the cyclic
path. Feed it blocks of frames (``observe``) and the cycle meter's boundaries (``end_cycle``);
ask for the figures when a page or an alarm needs them (``report``, JSON-able, ``joints`` as
the REST answer gives them); save and restore its state as a versioned document
(``to_document`` / ``from_document``). See docs/health.md for every figure and its limits.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np

from cobot_hmi.arms import Arm, arm_by_name
from cobot_hmi.health import document
from cobot_hmi.health.baseline import Baseline
from cobot_hmi.health.drift import CycleTimeDrift
from cobot_hmi.health.frames import FloatArray, FrameBlock
from cobot_hmi.health.friction import CellTable, friction_excess_percent
from cobot_hmi.health.health_settings import HealthSettings
from cobot_hmi.health.heat import HeatMonitor, cycle_heat
from cobot_hmi.health.knocks import KnockCounter
from cobot_hmi.health.life import LifeMeter
from cobot_hmi.health.samples import DistinctSamples
from cobot_hmi.health.signature import compare, quantiles, resample
from cobot_hmi.layout import LAYOUT_VERSION

MAX_PENDING_S: Final = 600.0
"""Frames kept for the cycle in progress: a longer cycle is measured without its signature."""
MIN_CYCLE_FRAMES: Final = 10
SIGNATURE_TOLERANCE: Final = 0.2
"""A cycle whose duration is off the baseline's by more than this fraction is another program
(or a disturbed cycle): no signature is compared."""
_WEEK_S: Final = 7 * 86_400.0


class HealthEngine:
    """One robot's health (see the module docstring)."""

    def __init__(self, arm: Arm, settings: HealthSettings | None = None) -> None:
        if len(arm.ratings) != len(arm.joints):
            raise ValueError(f"arm {arm.name} has no rated values for every joint (arms.py)")
        self.arm = arm
        self.settings = s = settings or HealthSettings()
        self.joints = len(arm.joints)
        rated_torque = np.array([r.rated_torque_nm for r in arm.ratings])
        self.rated_life_h = np.array([r.rated_life_h for r in arm.ratings])
        self.life = LifeMeter(rated_torque, np.array([r.rated_speed_deg_s for r in arm.ratings]))
        self.knocks = KnockCounter(
            rated_torque * s.knock_fraction_of_rated, s.shift_hours, s.shift_origin_s
        )
        self.recent = CellTable(s)
        self.samples = DistinctSamples()
        self.heat = HeatMonitor(self.joints)
        self.baseline: Baseline | None = None
        self.learning: Baseline | None = None
        self.history: list[dict[str, object]] = []
        """Every baseline's record, oldest first (the active one last once learned)."""
        self.drift: CycleTimeDrift | None = None
        self.signature_rms: FloatArray = np.full(self.joints, np.nan)
        self.signature_distribution: FloatArray = np.full(self.joints, np.nan)
        self.trend: list[list[float]] = []
        """[time, baseline id, friction % per joint (NaN: none)] every few cycles."""
        self.cycles = 0
        self.now_s = 0.0
        self.dropped_frames = 0
        self.last_time_s = -math.inf
        """The last frame's time: a frame not later is out of order (dropped)."""
        self._pending: list[FrameBlock] = []

    # ------------------------------------------------------------------ input

    def begin_baseline(
        self,
        reason: str,
        by: str,
        now_s: float,
        *,
        cycles: int | None = None,
        until_s: float | None = None,
    ) -> dict[str, object]:
        """Learn a new baseline from the next ``cycles`` whole cycles (or until ``until_s``);
        the one in use stays until it is learned. Returns its record."""
        if not reason.strip():
            raise ValueError("a baseline needs a reason")
        if cycles is None and until_s is None:
            cycles = self.settings.baseline_cycles
        if cycles is not None and cycles < 1:
            raise ValueError("a baseline needs at least one cycle")
        info: dict[str, object] = {
            "id": len(self.history) + 1,
            "reason": reason,
            "by": by,
            "arm": self.arm.name,
            "layout_version": LAYOUT_VERSION,
            "started_s": now_s,
            "finished_s": None,
            "target_cycles": cycles,
            "until_s": until_s,
        }
        self.learning = Baseline(self.settings, self.joints, info)
        return info

    def observe(self, block: FrameBlock) -> None:
        """Frames in time order, any number at a time (a cycle's, a second's). A frame with a
        value that is not a number, or not later than the last one, is dropped and counted
        (``dropped_frames``); arrays of the wrong shape are a ``ValueError`` and change
        nothing."""
        block, dropped = block.checked(self.last_time_s)
        if block.position_deg.shape[1] != self.joints:
            raise ValueError(f"expected {self.joints} joints, got {block.position_deg.shape[1]}")
        self.dropped_frames += dropped
        if len(block) == 0:
            return
        self.last_time_s = float(block.time_s[-1])
        self.now_s = float(block.time_s[-1])
        self.life.add(block)
        self.knocks.add(block)
        distinct, acceleration = self.samples.take(block, self.settings.jerk_tolerance_deg_s2)
        self.recent.add(distinct, acceleration)
        if self.learning is not None:
            self.learning.add_frames(distinct, acceleration)
        self._pending.append(block)
        while self._pending and self._pending[0].time_s[-1] < self.now_s - MAX_PENDING_S:
            self._pending.pop(0)

    def end_cycle(self, start_s: float, end_s: float, interrupted: bool = False) -> None:
        """A cycle ended (the cycle meter's ``Cycle``): its frames are those observed from
        ``start_s`` to ``end_s``."""
        start_s, end_s = float(start_s), float(end_s)  # a numpy scalar would leak into figures
        if not (math.isfinite(start_s) and math.isfinite(end_s) and end_s > start_s):
            raise ValueError(f"a cycle must end after it starts (from {start_s} to {end_s})")
        pending = FrameBlock.concatenate(self._pending) if self._pending else None
        rest = pending.between(end_s, np.inf) if pending is not None else None
        self._pending = [rest] if rest is not None and len(rest) else []
        s = self.settings
        self.recent.decay(1.0 - 1.0 / s.friction_memory_cycles)
        if pending is None or interrupted:
            return
        block = pending.between(start_s, end_s)
        if len(block) < MIN_CYCLE_FRAMES:
            return
        self.cycles += 1
        if self.learning is not None:
            self.learning.add_cycle(block, start_s, end_s)
            if self.learning.due(end_s):
                self._adopt(self.learning, end_s)
        elif self.baseline is not None:
            self._judge_cycle(self.baseline, block, start_s, end_s)
        if self.baseline is not None and self.cycles % s.trend_every_cycles == 0:
            self._trend_point(self.baseline, end_s)

    def adopt_learned(self, baseline: Baseline, finished_s: float) -> dict[str, object]:
        """Adopt a baseline another engine learned (from a recorded period, on the same arm and
        settings) as if learned here: numbered after this engine's, its record returned."""
        if self.learning is not None:
            raise ValueError("a baseline is being learned: it would be numbered the same")
        baseline.info["id"] = len(self.history) + 1
        self._adopt(baseline, finished_s)
        return baseline.info

    def _adopt(self, baseline: Baseline, now_s: float) -> None:
        baseline.info["finished_s"] = now_s
        baseline.info["cycles"] = baseline.cycles
        if self.baseline is not None:
            # What the old baseline would have read at the change: the trend spans it.
            baseline.info["friction_vs_previous_percent"] = friction_excess_percent(
                baseline.cells,
                self.baseline.cells,
                self.baseline.friction_per_speed(self.joints),
                self.settings,
            )
        self.history.append(baseline.info)
        self.baseline, self.learning = baseline, None
        mean_s, sigma_s = baseline.cycle_time()
        s = self.settings
        sigma_s = max(sigma_s, s.drift_min_sigma_fraction * mean_s)
        self.drift = CycleTimeDrift(mean_s, sigma_s, s.drift_cusum_k, s.drift_cusum_h)
        self.heat = HeatMonitor(self.joints)

    def _judge_cycle(
        self, baseline: Baseline, block: FrameBlock, start_s: float, end_s: float
    ) -> None:
        s = self.settings
        current_sq, settled = cycle_heat(block, s.thermal_time_constant_s)
        intercept, slope = baseline.heat.coefficients()
        self.heat.add(settled - (intercept + slope * current_sq), s.heat_memory_cycles)
        if self.drift is not None:
            self.drift.add(end_s - start_s, end_s)
        mean_s, _ = baseline.cycle_time()
        if abs((end_s - start_s) / mean_s - 1.0) <= SIGNATURE_TOLERANCE:
            deviation = compare(
                resample(block, start_s, end_s, s.signature_points),
                quantiles(block),
                baseline.signature,
                baseline.distribution,
            )
            alpha = 0.2
            for name, value in (
                ("signature_rms", deviation.rms_percent),
                ("signature_distribution", deviation.distribution_percent),
            ):
                old = getattr(self, name)
                setattr(self, name, np.where(np.isnan(old), value, old + alpha * (value - old)))

    def _trend_point(self, baseline: Baseline, now_s: float) -> None:
        friction = self.friction_percent()
        row = [now_s, float(baseline.info["id"])]  # type: ignore[arg-type]
        row += [np.nan if f is None else f for f in friction]
        self.trend.append(row)
        del self.trend[: -self.settings.trend_points]

    # ------------------------------------------------------------------ figures

    def friction_percent(self) -> list[float | None]:
        if self.baseline is None:
            return [None] * self.joints
        return friction_excess_percent(
            self.recent,
            self.baseline.cells,
            self.baseline.friction_per_speed(self.joints),
            self.settings,
        )

    def friction_since_first_percent(
        self, friction: list[float | None] | None = None
    ) -> list[float | None]:
        """Friction against the first baseline, through every re-baselining since (each
        baseline records its friction against the one before)."""
        factors = [1.0] * self.joints
        for info in self.history[1:]:
            steps = info.get("friction_vs_previous_percent")
            if not isinstance(steps, list):
                return [None] * self.joints
            for j, step in enumerate(steps):
                factors[j] = math.nan if step is None else factors[j] * (1.0 + step / 100.0)
        now = self.friction_percent() if friction is None else friction
        return [
            None if f is None or math.isnan(k) else 100.0 * (k * (1.0 + f / 100.0) - 1.0)
            for f, k in zip(now, factors, strict=True)
        ]

    def friction_per_week(self) -> list[float | None]:
        """The slope of each joint's friction over the last two weeks' trend points, in % a
        week; ``None`` with fewer than three points or less than an hour between them."""
        rows = np.array([r for r in self.trend if r[0] >= self.now_s - 2 * _WEEK_S])
        if rows.shape[0] < 3 or rows[-1, 0] - rows[0, 0] < 3600.0:
            return [None] * self.joints
        out: list[float | None] = []
        for j in range(self.joints):
            values = rows[:, 2 + j]
            ok = ~np.isnan(values)
            if ok.sum() < 3:
                out.append(None)
                continue
            slope = np.polyfit(rows[ok, 0], values[ok], 1)[0]
            out.append(float(slope * _WEEK_S))
        return out

    def report(self, now_s: float | None = None) -> dict[str, object]:
        """Every figure and each joint's verdict, JSON-able (docs/health.md)."""
        from cobot_hmi.health.report import build_report

        return build_report(self, self.now_s if now_s is None else now_s)

    # ------------------------------------------------------------------ state

    def to_document(self) -> dict[str, object]:
        from cobot_hmi.health.report import engine_state

        return document.wrap(engine_state(self))

    @classmethod
    def from_document(
        cls, doc: dict[str, object], settings: HealthSettings | None = None
    ) -> HealthEngine:
        from cobot_hmi.health.report import restore_engine

        body = document.unwrap(doc)
        engine = cls(arm_by_name(str(body["arm"])), settings)
        restore_engine(engine, body)
        return engine
