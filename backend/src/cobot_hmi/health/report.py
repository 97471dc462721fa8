"""Layer: health (pure). Imports the other ``health`` modules.

What ``HealthEngine`` answers: the report (each joint's verdict, reason and figures, the
robot's cycle time and knocks) and the body of its state document, kept apart from the engine
so the engine stays about frames and cycles.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from cobot_hmi.health.baseline import Baseline
from cobot_hmi.health.drift import CycleTimeDrift
from cobot_hmi.health.frames import FloatArray
from cobot_hmi.health.friction import CellTable
from cobot_hmi.health.verdict import Finding, day_text, friction_text, level_of, verdict

if TYPE_CHECKING:
    from cobot_hmi.health.engine import HealthEngine


def _round(value: float | None, digits: int = 2) -> float | None:
    if value is None or not math.isfinite(value):
        return None
    return round(float(value), digits)


LIFE_DATE_HORIZON_H = 100 * 8766.0
"""Beyond a hundred years the remaining life at this week's duty names no date a planner uses
(a joint that hardly moves has a remaining life of millennia): the hours stay, the date is
null (the health page says "more than 100 years" from the same bound)."""


def life_end_date(now_s: float, remaining_h: float | None) -> str | None:
    """The UTC date the reducer's rated life runs out at this week's duty; ``None`` when the
    duty is not known or the date lies beyond ``LIFE_DATE_HORIZON_H``."""
    if remaining_h is None or not math.isfinite(remaining_h) or remaining_h > LIFE_DATE_HORIZON_H:
        return None
    return time.strftime("%Y-%m-%d", time.gmtime(now_s + max(0.0, remaining_h) * 3600.0))


def _joint(
    engine: HealthEngine, j: int, now_s: float, figures: dict[str, list[Any]]
) -> dict[str, object]:
    s = engine.settings
    rating = engine.arm.ratings[j]
    friction, per_week = figures["friction"][j], figures["per_week"][j]
    heat = figures["heat"][j]
    life_used = 100.0 * engine.life.aged_h[j] / rating.rated_life_h
    rate = figures["rate"][j]
    remaining_h = (rating.rated_life_h - engine.life.aged_h[j]) / rate if rate > 0 else None
    findings: list[Finding] = []
    baseline = engine.baseline
    if friction is not None and baseline is not None:
        level = level_of(friction, s.friction_watch_percent, s.friction_act_percent)
        base_s = float(baseline.info["finished_s"])  # type: ignore[arg-type]
        findings.append(Finding(level, friction_text(friction, base_s, per_week)))
    heat_c = None if heat is None or not math.isfinite(heat) else float(heat)
    if heat_c is not None:
        level = level_of(heat_c, s.heat_watch_c, s.heat_act_c)
        findings.append(Finding(level, f"motor {heat_c:.1f} °C hotter than its current explains"))
    level = level_of(life_used, s.life_watch_percent, s.life_act_percent)
    findings.append(Finding(level, f"{life_used:.1f} % of its rated reducer life used"))
    collisions = engine.knocks.collisions[j]
    if collisions:
        findings.append(
            Finding(
                1,
                f"{collisions} external-torque peak(s) over "
                f"{engine.knocks.threshold_nm[j]:.0f} N·m this shift",
            )
        )
    quiet = _quiet(engine, friction, heat_c, life_used)
    word, reason = verdict(j + 1, findings, quiet)
    return {
        "joint": j + 1,
        "verdict": word,
        "reason": reason,
        "friction_percent": _round(friction),
        "friction_percent_per_week": _round(per_week),
        "friction_percent_since_first_baseline": _round(figures["since_first"][j]),
        "friction_reference": figures["reference"][j],
        "signature_rms_percent": _round(float(engine.signature_rms[j])),
        "signature_distribution_percent": _round(float(engine.signature_distribution[j])),
        "heat_excess_c": _round(heat_c),
        "life_used_percent": _round(life_used, 4),
        "life_remaining_h": _round(remaining_h, 0),
        "life_end_date": life_end_date(now_s, remaining_h),
        "collisions_this_shift": collisions,
        "rated": {
            "torque_nm": rating.rated_torque_nm,
            "speed_deg_s": rating.rated_speed_deg_s,
            "life_h": rating.rated_life_h,
            "assumed": rating.assumed,
        },
    }


def _quiet(
    engine: HealthEngine, friction: float | None, heat_c: float | None, life_used: float
) -> str:
    if engine.baseline is None:
        learning = engine.learning
        if learning is None:
            return "no baseline yet: name the cycles to learn it from"
        target = learning.info.get("target_cycles")
        of = f" of {target}" if target else ""
        return f"learning its baseline ({learning.cycles}{of} cycles)"
    base = day_text(float(engine.baseline.info["finished_s"]))  # type: ignore[arg-type]
    parts = []
    if friction is None:
        parts.append("friction not comparable with its baseline of " + base + " yet")
    else:
        parts.append(f"friction {friction:+.1f} % against its baseline of {base}")
    if heat_c is not None:
        parts.append(f"heat {heat_c:+.1f} °C for its duty")
    parts.append(f"{life_used:.2f} % of rated life used")
    return ", ".join(parts)


def _cycle_time(drift: CycleTimeDrift | None) -> dict[str, object]:
    if drift is None:
        return {"verdict": "ok", "reason": "no baseline yet", "baseline_s": None}
    change = drift.change_percent
    word = "watch" if drift.detected else "ok"
    if drift.detected and change is not None:
        reason = (
            f"cycle time {abs(change):.1f} % {'longer' if change > 0 else 'shorter'} than its "
            f"baseline of {drift.mean_s:.2f} s"
        )
    else:
        reason = f"cycle time as in its baseline ({drift.mean_s:.2f} s)"
    return {
        "verdict": word,
        "reason": reason,
        "baseline_s": _round(drift.mean_s, 3),
        "recent_s": _round(drift.recent_s, 3),
        "change_percent": _round(change),
        "drift_detected": bool(drift.detected),
        "detected_at": drift.detected_at_s,
        "cycles": drift.cycles,
    }


def build_report(engine: HealthEngine, now_s: float) -> dict[str, object]:
    heat = engine.heat.relative_c()
    friction = engine.friction_percent()
    figures: dict[str, list[Any]] = {
        "friction": friction,
        "per_week": engine.friction_per_week(),
        "since_first": engine.friction_since_first_percent(friction),
        "reference": engine.baseline.friction_reference(engine.joints)
        if engine.baseline is not None
        else [None] * engine.joints,
        "heat": [float(h) for h in heat],
        "rate": [float(r) for r in engine.life.week_rate()],
    }
    joints = [_joint(engine, j, now_s, figures) for j in range(engine.joints)]
    knocks = engine.knocks
    return {
        "arm": engine.arm.name,
        "time": now_s,
        "cycles": engine.cycles,
        "dropped_frames": engine.dropped_frames,
        "baseline": engine.history[-1] if engine.baseline is not None else None,
        "learning": engine.learning.info | {"cycles": engine.learning.cycles}
        if engine.learning is not None
        else None,
        "baselines": engine.history,
        "joints": joints,
        "cycle_time": _cycle_time(engine.drift),
        "knocks": {
            "shift_start": knocks.shift_start_s,
            "collisions": knocks.collisions,
            **knocks.counts,
            "events": knocks.events[-20:],
        },
    }


def engine_state(engine: HealthEngine) -> dict[str, object]:
    return {
        "arm": engine.arm.name,
        "cycles": engine.cycles,
        "now_s": engine.now_s,
        "last_time_s": engine.last_time_s if math.isfinite(engine.last_time_s) else None,
        "dropped_frames": engine.dropped_frames,
        "history": engine.history,
        "baseline": engine.baseline.to_state() if engine.baseline is not None else None,
        "learning": engine.learning.to_state() if engine.learning is not None else None,
        "recent": engine.recent.to_state(),
        "last_sample": engine.samples.to_state(),
        "heat_excess_c": _list(engine.heat.excess_c),
        "signature_rms": _list(engine.signature_rms),
        "signature_distribution": _list(engine.signature_distribution),
        "drift": engine.drift.to_state() if engine.drift is not None else None,
        "life": engine.life.to_state(),
        "knocks": engine.knocks.to_state(),
        "trend": [[None if math.isnan(v) else v for v in row] for row in engine.trend],
    }


def _list(values: FloatArray) -> list[float | None]:
    return [None if math.isnan(v) else float(v) for v in values]


def _array(values: object) -> FloatArray:
    assert isinstance(values, list)
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


def restore_engine(engine: HealthEngine, body: dict[str, object]) -> None:
    s, joints = engine.settings, engine.joints
    engine.cycles = int(body["cycles"])  # type: ignore[call-overload]
    engine.now_s = float(body["now_s"])  # type: ignore[arg-type]
    last = body["last_time_s"]
    engine.last_time_s = -math.inf if last is None else float(last)  # type: ignore[arg-type]
    engine.dropped_frames = int(body["dropped_frames"])  # type: ignore[call-overload]
    engine.history = list(body["history"])  # type: ignore[call-overload]
    for name in ("baseline", "learning"):
        state = body[name]
        setattr(engine, name, None if state is None else Baseline.from_state(s, joints, state))  # type: ignore[arg-type]
    engine.recent = CellTable.from_state(s, body["recent"])  # type: ignore[arg-type]
    engine.samples.restore(body["last_sample"])
    engine.heat.excess_c = _array(body["heat_excess_c"])
    engine.signature_rms = _array(body["signature_rms"])
    engine.signature_distribution = _array(body["signature_distribution"])
    drift = body["drift"]
    engine.drift = None if drift is None else CycleTimeDrift(**drift)  # type: ignore[arg-type]
    engine.life.restore(body["life"])  # type: ignore[arg-type]
    engine.knocks.restore(body["knocks"])  # type: ignore[arg-type]
    engine.trend = [[np.nan if v is None else float(v) for v in row] for row in body["trend"]]  # type: ignore[attr-defined]
