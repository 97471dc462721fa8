"""Layer: service. Robot health in the service's database (the ``health_state``,
``health_baselines`` and ``health_snapshots`` tables, created by ``service.storage.migrations``
step 9), read and written on the store's one worker thread (``Store.call``).

- ``health_state``: one row per robot, the engine's whole state as its versioned JSON document
  (``cobot_hmi.health.document``: ``kind`` and ``format_version``), replaced on each save. A
  restart restores it, so life used and knocks counted go on from where they were saved: the
  frames after the save are counted once (never again: the engine drops a frame not later than
  the last it counted).
- ``health_baselines``: every baseline of the robot, with who set it, why, when, on which arm
  and layout, from which cycles; rows are added and updated, never removed, so the trends can
  span a re-baselining.
- ``health_snapshots``: the figures every ``health_snapshot_s`` (each joint's verdict, friction,
  life used, heat, knocks): the trends and the weekly report.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from cobot_hmi.service.storage.store import Store

SNAPSHOT_FIELDS: Final = (
    "verdict",
    "friction_percent",
    "friction_percent_since_first_baseline",
    "signature_rms_percent",
    "heat_excess_c",
    "life_used_percent",
    "life_remaining_h",
    "collisions_this_shift",
)
"""Each joint's figures a snapshot keeps (``report["joints"]``)."""


@dataclass(frozen=True, slots=True)
class Snapshot:
    time: float
    baseline_id: int | None
    verdict: str
    cycles: int
    joints: list[dict[str, object]]
    """Per joint: ``joint`` and the ``SNAPSHOT_FIELDS``."""


def snapshot_of(report: dict[str, object], verdict: str) -> Snapshot:
    """The snapshot of a report (``HealthEngine.report`` and the worst ``verdict``)."""
    joints = report["joints"]
    assert isinstance(joints, list)
    baseline = report.get("baseline")
    baseline_id = baseline.get("id") if isinstance(baseline, dict) else None
    time_s = report["time"]
    cycles = report["cycles"]
    assert isinstance(time_s, int | float) and isinstance(cycles, int)
    return Snapshot(
        float(time_s),
        baseline_id if isinstance(baseline_id, int) else None,
        verdict,
        cycles,
        [{"joint": j["joint"], **{k: j.get(k) for k in SNAPSHOT_FIELDS}} for j in joints],
    )


def baseline_row(robot: str, info: dict[str, object]) -> tuple[object, ...]:
    """A baseline's record (the engine's ``info``) as its ``health_baselines`` row."""
    return (
        robot,
        info["id"],
        info["started_s"],
        info["by"],
        info["reason"],
        info["arm"],
        info["layout_version"],
        info.get("target_cycles"),
        info.get("cycles"),
        info["started_s"],
        info.get("finished_s"),
        json.dumps(info),
    )


class HealthStore:
    """Load and save one cell's health (see the module docstring)."""

    def __init__(self, store: Store) -> None:
        self._store = store

    async def load(self, robot: str) -> dict[str, object] | None:
        """The robot's saved engine document, or ``None``."""

        def read(db: sqlite3.Connection) -> object:
            row = db.execute("SELECT document FROM health_state WHERE robot = ?", (robot,))
            found = row.fetchone()
            return None if found is None else found[0]

        text = await self._store.call(read, fsync=False)
        if not isinstance(text, str):
            return None
        document = json.loads(text)
        assert isinstance(document, dict)
        return document

    async def save(
        self,
        robot: str,
        saved_at: float,
        document: dict[str, object],
        baselines: Sequence[dict[str, object]],
    ) -> None:
        """The engine's document and its baselines' records, in one transaction, durably."""
        text = json.dumps(document)
        rows = [baseline_row(robot, info) for info in baselines]

        def write(db: sqlite3.Connection) -> None:
            db.execute(
                "INSERT INTO health_state (robot, saved_at, document) VALUES (?, ?, ?) "
                "ON CONFLICT (robot) DO UPDATE SET saved_at = excluded.saved_at, "
                "document = excluded.document",
                (robot, saved_at, text),
            )
            db.executemany(
                "INSERT INTO health_baselines (robot, id, created_at, created_by, reason, arm, "
                "layout_version, target_cycles, cycles, learned_from, learned_to, record) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (robot, id) DO UPDATE "
                "SET cycles = excluded.cycles, learned_to = excluded.learned_to, "
                "target_cycles = excluded.target_cycles, record = excluded.record",
                rows,
            )

        await self._store.call(write)

    async def add_snapshot(self, robot: str, snapshot: Snapshot) -> None:
        def write(db: sqlite3.Connection) -> None:
            db.execute(
                "INSERT INTO health_snapshots (robot, time, baseline_id, verdict, cycles, joints)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                (
                    robot,
                    snapshot.time,
                    snapshot.baseline_id,
                    snapshot.verdict,
                    snapshot.cycles,
                    json.dumps(snapshot.joints),
                ),
            )

        await self._store.call(write, fsync=False)

    async def snapshots(
        self, robot: str, since: float | None, until: float | None, limit: int
    ) -> list[Snapshot]:
        """The robot's snapshots in ``[since, until)``, oldest first (the newest ``limit``)."""
        clauses, params = ["robot = ?"], [robot]
        if since is not None:
            clauses.append("time >= ?")
            params.append(since)  # type: ignore[arg-type]
        if until is not None:
            clauses.append("time < ?")
            params.append(until)  # type: ignore[arg-type]

        def read(db: sqlite3.Connection) -> list[tuple[object, ...]]:
            return db.execute(
                "SELECT time, baseline_id, verdict, cycles, joints FROM health_snapshots WHERE "
                f"{' AND '.join(clauses)} ORDER BY time DESC LIMIT ?",
                (*params, limit),
            ).fetchall()

        rows = await self._store.call(read, fsync=False)
        return [_snapshot(row) for row in reversed(rows)]

    async def baselines(self, robot: str) -> list[dict[str, object]]:
        """Every baseline record of the robot, oldest first."""

        def read(db: sqlite3.Connection) -> list[tuple[object, ...]]:
            return db.execute(
                "SELECT record FROM health_baselines WHERE robot = ? ORDER BY id", (robot,)
            ).fetchall()

        rows = await self._store.call(read, fsync=False)
        records = [json.loads(str(row[0])) for row in rows]
        return [r for r in records if isinstance(r, dict)]


def _snapshot(row: tuple[object, ...]) -> Snapshot:
    time_s, baseline_id, verdict, cycles, joints = row
    assert isinstance(time_s, float | int) and isinstance(cycles, int)
    return Snapshot(
        float(time_s),
        baseline_id if isinstance(baseline_id, int) else None,
        str(verdict),
        cycles,
        json.loads(str(joints)),
    )
