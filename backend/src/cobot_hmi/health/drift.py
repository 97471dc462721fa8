"""Layer: health (pure). Imports nothing of the project.

Cycle-time drift, detected as it happens: a two-sided CUSUM of each whole cycle's duration,
standardised by the baseline's mean and spread (the spread taken as at least a fraction of the
mean, so an emulator's exact cycles do not make every frame of jitter an alarm). ``S⁺`` and
``S⁻`` are capped at twice the decision level, so they fall back below it within a few cycles
once the durations return; an EWMA of the durations gives the change in %.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(slots=True)
class CycleTimeDrift:
    mean_s: float
    sigma_s: float
    k: float
    h: float
    high: float = 0.0
    low: float = 0.0
    recent_s: float | None = None
    detected_at_s: float | None = None
    cycles: int = 0

    def add(self, duration_s: float, end_s: float) -> None:
        z = (duration_s - self.mean_s) / self.sigma_s
        cap = 2.0 * self.h
        self.high = min(cap, max(0.0, self.high + z - self.k))
        self.low = min(cap, max(0.0, self.low - z - self.k))
        alpha = 0.2
        self.recent_s = (
            duration_s
            if self.recent_s is None
            else self.recent_s + alpha * (duration_s - self.recent_s)
        )
        self.cycles += 1
        if self.detected:
            if self.detected_at_s is None:
                self.detected_at_s = end_s
        else:
            self.detected_at_s = None

    @property
    def detected(self) -> bool:
        return bool(self.high >= self.h or self.low >= self.h)

    @property
    def change_percent(self) -> float | None:
        if self.recent_s is None:
            return None
        return 100.0 * (self.recent_s - self.mean_s) / self.mean_s

    def to_state(self) -> dict[str, object]:
        return asdict(self)
