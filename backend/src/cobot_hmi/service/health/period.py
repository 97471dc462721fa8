"""Layer: service. A baseline learned from a period the operator names (issue 40): the robot's
recorded frames of the period (the recorder's history, ``history.query.iter_raw``, one segment
at a time) and the cycles the cycle meter stored in it, fed to a fresh engine of the robot's arm
and settings (``begin_baseline``, ``observe``, ``end_cycle``), as the live engine would have
learned them then. Runs on a worker thread (never the web loop); the live engine adopts the
result (``HealthEngine.adopt_learned``) as it adopts one learned from the next cycles.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from cobot_hmi.arms import Arm
from cobot_hmi.health import FrameBlock, HealthEngine, HealthSettings
from cobot_hmi.health.baseline import Baseline
from cobot_hmi.history.query import iter_raw
from cobot_hmi.history.schema import ELEMENTS, TIME, raw_from_columns, time_seconds

MIN_PERIOD_CYCLES: Final = 2
"""Whole cycles a period must hold: a mean cycle time and its spread."""
_COLUMNS: Final = (TIME, *(e.name for e in ELEMENTS))


class PeriodError(ValueError):
    """Why a period cannot be learned from, in words (answered 409)."""


@dataclass(frozen=True, slots=True)
class PeriodRequest:
    """Who asks for a period's baseline, why, when, and the period (s since the epoch)."""

    reason: str
    by: str
    now_s: float
    from_s: float
    to_s: float


@dataclass(frozen=True, slots=True)
class PeriodCycle:
    start_s: float
    end_s: float
    interrupted: bool


def learn_period(
    arm: Arm,
    settings: HealthSettings,
    *,
    history_root: Path,
    robot: str,
    cycles: Sequence[PeriodCycle],
    request: PeriodRequest,
) -> Baseline:
    """The baseline of ``cycles`` (oldest first, inside the period) learned from the recorded
    frames. ``PeriodError`` when the period holds no recording or too few whole cycles with
    their frames."""
    from_s, to_s = request.from_s, request.to_s
    whole = [c for c in cycles if not c.interrupted]
    if len(whole) < MIN_PERIOD_CYCLES:
        raise PeriodError(
            f"the period holds {len(whole)} whole measured cycles; a baseline needs at least "
            f"{MIN_PERIOD_CYCLES}"
        )
    engine = HealthEngine(arm, settings)
    record = engine.begin_baseline(request.reason, request.by, request.now_s, cycles=len(whole))
    record.update(period_from_s=from_s, period_to_s=to_s)
    waiting = list(cycles)
    frames = 0
    for table in iter_raw(history_root, robot, _COLUMNS, from_s, to_s):
        if table.num_rows == 0:
            continue
        raw = raw_from_columns(table)
        times_s = time_seconds(table).tolist()
        engine.observe(FrameBlock.from_payloads(times_s, [row.tobytes() for row in raw]))
        frames += table.num_rows
        while waiting and waiting[0].end_s <= engine.last_time_s:
            cycle = waiting.pop(0)
            engine.end_cycle(cycle.start_s, cycle.end_s, cycle.interrupted)
    if frames == 0:
        raise PeriodError("the period holds no recorded frames of the robot (history)")
    for cycle in waiting:  # the last cycle ends with the recording's last frame
        engine.end_cycle(cycle.start_s, cycle.end_s, cycle.interrupted)
    learned = engine.baseline
    if learned is None:
        learning = engine.learning
        got = 0 if learning is None else learning.cycles
        raise PeriodError(
            f"the recording holds the frames of {got} of the period's {len(whole)} whole "
            "cycles: a baseline needs every one it counts"
        )
    return learned
