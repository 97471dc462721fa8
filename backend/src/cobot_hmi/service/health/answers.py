"""Layer: service (pure). What the health routes answer, from the engine's report and the stored
snapshots: the report with the robot's verdict, the baselines in the API's words, the trend's
points and the weekly report's CSV (one row per joint per day of the plant's time zone)."""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from datetime import datetime
from typing import Final

from cobot_hmi.service.health.monitor import worst_verdict
from cobot_hmi.service.health.store import SNAPSHOT_FIELDS, Snapshot
from cobot_hmi.service.plant_time import PLANT_ZONE

REPORT_COLUMNS: Final = (
    "robot",
    "period_from",
    "period_to",
    "day",
    "time",
    "baseline_id",
    "joint",
    *SNAPSHOT_FIELDS,
)
"""The weekly report's columns: the period it covers in each row (ISO 8601), the plant's day,
the time of that day's last snapshot, and the joint's figures then."""


def baseline_answer(
    info: Mapping[str, object], *, active: bool, learning: bool, cycles: object = None
) -> dict[str, object]:
    """``models_health.HealthBaseline`` of a baseline's record (the engine's ``info``)."""
    return {
        "id": info["id"],
        "reason": info["reason"],
        "created_by": info["by"],
        "created_at": info["started_s"],
        "arm": info["arm"],
        "layout_version": info["layout_version"],
        "target_cycles": info.get("target_cycles"),
        "cycles": cycles if cycles is not None else info.get("cycles"),
        # A period's baseline was learned from recorded frames: the period, not when asked.
        "learned_from": info.get("period_from_s", info["started_s"]),
        "learned_to": info.get("period_to_s", info.get("finished_s")),
        "active": active,
        "learning": learning,
    }


def report_answer(
    robot: str, report: Mapping[str, object], queue_dropped: int
) -> dict[str, object]:
    """``models_health.HealthReport`` of the engine's report."""
    joints = report["joints"]
    assert isinstance(joints, list)
    verdict = worst_verdict(joints)
    baseline, learning = report.get("baseline"), report.get("learning")
    engine_dropped = report.get("dropped_frames", 0)
    assert isinstance(engine_dropped, int)
    knocks = dict(report["knocks"])  # type: ignore[call-overload]
    return {
        "robot": robot,
        "arm": report["arm"],
        "time": report["time"],
        "verdict": verdict,
        "maintenance_due": verdict != "ok",
        "cycles": report["cycles"],
        "dropped_frames": engine_dropped + queue_dropped,
        "joints": joints,
        "cycle_time": report["cycle_time"],
        "knocks": knocks,
        "baseline": baseline_answer(baseline, active=True, learning=False)
        if isinstance(baseline, Mapping)
        else None,
        "learning": baseline_answer(
            learning, active=False, learning=True, cycles=learning.get("cycles")
        )
        if isinstance(learning, Mapping)
        else None,
    }


def baselines_answer(
    records: Sequence[Mapping[str, object]],
    active_id: object,
    learning_id: object,
    learning_cycles: int | None,
) -> list[dict[str, object]]:
    """Every baseline (``records``, oldest first), which is active, which is learning (and
    from how many cycles so far)."""
    answers = []
    for info in records:
        learning = info["id"] == learning_id and not info.get("finished_s")
        answers.append(
            baseline_answer(
                info,
                active=info["id"] == active_id,
                learning=learning,
                cycles=learning_cycles if learning else None,
            )
        )
    return answers


def trend_answer(robot: str, snapshots: Sequence[Snapshot]) -> dict[str, object]:
    """``models_health.HealthTrend``."""
    return {
        "robot": robot,
        "points": [
            {
                "time": s.time,
                "baseline_id": s.baseline_id,
                "verdict": s.verdict,
                "cycles": s.cycles,
                "joints": s.joints,
            }
            for s in snapshots
        ],
    }


def _iso(epoch_s: float) -> str:
    return datetime.fromtimestamp(epoch_s, PLANT_ZONE.zone).isoformat()


def report_csv(robot: str, snapshots: Sequence[Snapshot], from_s: float, to_s: float) -> str:
    """The weekly report: per day (the plant's), the day's last snapshot, one row per joint."""
    last_of_day: dict[str, Snapshot] = {}
    for snapshot in snapshots:  # oldest first: a later one of the day replaces an earlier
        last_of_day[datetime.fromtimestamp(snapshot.time, PLANT_ZONE.zone).date().isoformat()] = (
            snapshot
        )
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(REPORT_COLUMNS)
    for day, snapshot in last_of_day.items():
        for joint in snapshot.joints:
            row: list[object] = [
                robot,
                _iso(from_s),
                _iso(to_s),
                day,
                _iso(snapshot.time),
                snapshot.baseline_id,
                joint.get("joint"),
                *(joint.get(name) for name in SNAPSHOT_FIELDS),
            ]
            writer.writerow(["" if value is None else value for value in row])
    return out.getvalue()


__all__ = [
    "REPORT_COLUMNS",
    "baseline_answer",
    "baselines_answer",
    "report_answer",
    "report_csv",
    "trend_answer",
    "worst_verdict",
]
