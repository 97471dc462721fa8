"""Layer: health (pure). Imports nothing of the project.

The engine's thresholds and bins, each with its unit and why (docs/health.md, "Thresholds").
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class HealthSettings:
    """Defaults tuned on the emulated arm (docs/health.md says how and what they assume)."""

    friction_watch_percent: float = 7.0
    friction_act_percent: float = 18.0
    friction_memory_cycles: float = 10.0
    """The recent friction is an exponentially weighted mean over about this many cycles."""
    position_bin_deg: float = 10.0
    speed_bin_deg_s: float = 5.0
    temperature_band_c: float = 2.0
    """Friction is compared within bands this wide of the motor's temperature: friction drops
    as a gear warms, so a cold morning is compared with nothing rather than read as wear."""
    min_speed_deg_s: float = 2.0
    """Slower frames (stiction, a reversal) tell nothing of friction."""
    jerk_tolerance_deg_s2: float = 10.0
    """A sample whose acceleration before and after differ by more than this (and 10 %) straddles
    a change of acceleration: left out of the friction fit."""
    min_cell_frames: float = 6.0
    """Samples a cell needs before its three-term fit counts: with three a few samples of
    uneven spacing or noise made a healthy joint read ±20 % (tests/test_health_receive_jitter)."""
    heat_watch_c: float = 5.0
    heat_act_c: float = 10.0
    thermal_time_constant_s: float = 180.0
    """The motors' first-order thermal time constant: an assumption (docs/health.md)."""
    heat_memory_cycles: float = 5.0
    life_watch_percent: float = 80.0
    life_act_percent: float = 100.0
    knock_fraction_of_rated: float = 0.15
    """An external torque above this fraction of the joint's rated torque is a knock."""
    shift_hours: float = 8.0
    shift_origin_s: float = 6 * 3600.0
    """Shifts start at this many seconds after midnight (UTC epoch seconds) and every
    ``shift_hours``."""
    drift_cusum_k: float = 0.5
    drift_cusum_h: float = 5.0
    drift_min_sigma_fraction: float = 0.005
    """The cycle time's spread is taken as at least this fraction of its mean."""
    signature_points: int = 100
    baseline_cycles: int = 50
    trend_every_cycles: int = 10
    trend_points: int = 500
