"""Robot health's service parts without the network, fed the emulated arm faster than real
time (``HealthSimulation``, the engine's own tests' source of frames): the state saved in the
real SQLite database and restored after a "restart" gives the same figures and counts the
frames after it once; a joint's advisory alarm comes with its watch, is acknowledged and
shelved as any other, and clears once the joint reads ok again; the ``health`` event and the
answers the routes give."""

from __future__ import annotations

import csv
import io
import sqlite3
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
from pydantic import ValidationError

from cobot_hmi.cli.health_verb import HealthSimulation
from cobot_hmi.emulator.robot.wear import JointWear
from cobot_hmi.health import FrameBlock, HealthEngine
from cobot_hmi.service.alarms.definitions import Priority
from cobot_hmi.service.alarms.engine import AlarmEngine, AlarmRefusedError
from cobot_hmi.service.health.answers import report_answer, report_csv, trend_answer
from cobot_hmi.service.health.health_service_settings import HealthServiceSettings
from cobot_hmi.service.health.service import advise, health_event
from cobot_hmi.service.health.store import HealthStore, snapshot_of
from cobot_hmi.service.storage.migrations import SCHEMA_VERSION
from cobot_hmi.service.storage.store import Store

ROBOT = "left"
BASELINE_CYCLES = 30


@pytest.fixture
async def store(tmp_path: Path) -> AsyncIterator[Store]:
    opened = Store(tmp_path / "hmi.db")
    await opened.open()
    try:
        yield opened
    finally:
        await opened.close()


def _baselined() -> HealthSimulation:
    sim = HealthSimulation()
    sim.engine.begin_baseline("commissioning", "olivia", sim.now_s, cycles=BASELINE_CYCLES)
    sim.run(BASELINE_CYCLES)
    assert sim.engine.baseline is not None
    return sim


def _cycle(sim: HealthSimulation) -> tuple[FrameBlock, float, float]:
    """One more cycle of the arm's frames (not fed), and its start and end."""
    frames = sim.arm.cycle(sim.now_s, sim.temperatures, sim.wear, sim.rng)
    start_s, end_s = sim.now_s, sim.now_s + sim.arm.duration_s
    sim.temperatures = sim.arm.end_temperatures(frames)
    sim.now_s = end_s
    return FrameBlock(*frames), start_s, end_s


def _figures(engine: HealthEngine, now_s: float) -> list[tuple[Any, ...]]:
    joints = engine.report(now_s)["joints"]
    assert isinstance(joints, list)
    return [
        (j["verdict"], j["life_used_percent"], j["friction_percent"], j["collisions_this_shift"])
        for j in joints
    ]


async def test_a_restart_restores_the_figures_and_counts_later_frames_once(
    store: Store, tmp_path: Path
) -> None:
    sim = _baselined()
    health = HealthStore(store)
    records = [dict(info) for info in sim.engine.history]
    await health.save(ROBOT, sim.now_s, sim.engine.to_document(), records)
    await store.close()  # the service stops ...
    reopened = Store(tmp_path / "hmi.db")
    await reopened.open()  # ... and starts again
    try:
        document = await HealthStore(reopened).load(ROBOT)
        assert document is not None and document["format_version"] == 1
        restored = HealthEngine.from_document(document)
        assert _figures(restored, sim.now_s) == _figures(sim.engine, sim.now_s)
        assert restored.history == sim.engine.history
        stored = await HealthStore(reopened).baselines(ROBOT)
        assert [(b["id"], b["reason"], b["by"]) for b in stored] == [(1, "commissioning", "olivia")]

        block, start_s, end_s = _cycle(sim)
        for engine in (sim.engine, restored):  # further frames: added once to each
            engine.observe(block)
            engine.end_cycle(start_s, end_s)
        assert _figures(restored, end_s) == _figures(sim.engine, end_s)
        life = restored.report(end_s)["joints"][0]["life_used_percent"]  # type: ignore[index]
        dropped = restored.dropped_frames
        restored.observe(block)  # the same frames again (a replay): none counted twice
        assert restored.report(end_s)["joints"][0]["life_used_percent"] == life  # type: ignore[index]
        assert restored.dropped_frames == dropped + len(block)
    finally:
        await reopened.close()
    with sqlite3.connect(tmp_path / "hmi.db") as db:
        assert db.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        (saved,) = db.execute("SELECT count(*) FROM health_state").fetchone()
    assert saved == 1


def _alarm_engine() -> AlarmEngine:
    return AlarmEngine(
        ROBOT,
        motor_temperature_c=80.0,
        motor_temperature_deadband_c=2.0,
        gap_rate_per_min=10.0,
        connection_delay_s=2.0,
        shelve_max_s=86_400.0,
        shelve_max_by_priority_s={"high": 3600.0, "medium": 3600.0, "low": 3600.0},
    )


def _active(alarms: AlarmEngine) -> dict[str, dict[str, Any]]:
    return {str(a["key"]): a for a in alarms.current() if a["active"]}


def test_a_watch_raises_an_advisory_alarm_that_clears_when_ok_again() -> None:
    sim = _baselined()
    alarms = _alarm_engine()
    assert advise(alarms, sim.engine.report(sim.now_s), sim.now_s) == []
    sim.add_wear(3, JointWear(friction_percent=25.0))
    sim.run(50)
    report = sim.engine.report(sim.now_s)
    joints: list[dict[str, Any]] = report["joints"]  # type: ignore[assignment]
    assert joints[2]["verdict"] in ("watch", "act"), joints[2]
    events = advise(alarms, report, sim.now_s)
    assert [e["alarm"]["key"] for e in events] == [  # type: ignore[index]
        f"health.{j['joint']}" for j in joints if j["verdict"] != "ok"
    ]
    advisory = _active(alarms)["health.3"]
    assert advisory["priority"] == Priority.ADVISORY.value and advisory["priority_rank"] == 4
    assert advisory["message"] == joints[2]["reason"] and "J3" in advisory["message"]
    assert all(Priority(str(a["priority"])).rank < 4 for a in alarms.all() if a["kind"] != "health")
    assert advise(alarms, report, sim.now_s) == []  # the same verdicts: nothing new
    # Acknowledged and shelved as any other alarm.
    _, changed = alarms.acknowledge(f"{ROBOT}:health.3", "olivia", "planned for Friday")
    assert changed
    shelved = alarms.shelve(f"{ROBOT}:health.3", "olivia", "reducer ordered", 8 * 3600.0)
    assert shelved["shelved"] is True
    # A new reducer: re-baselined, the verdicts restart from it and the alarm clears.
    sim.engine.begin_baseline("reducer J3 changed", "olivia", sim.now_s, cycles=BASELINE_CYCLES)
    sim.run(BASELINE_CYCLES + 20)
    report = sim.engine.report(sim.now_s)
    assert {j["verdict"] for j in report["joints"]} == {"ok"}  # type: ignore[attr-defined]
    advise(alarms, report, sim.now_s)
    assert "health.3" not in _active(alarms)


def test_the_health_event_and_the_answers() -> None:
    sim = _baselined()
    sim.add_wear(1, JointWear(friction_percent=25.0))
    sim.run(50)
    report = sim.engine.report(sim.now_s)
    event = health_event(report, sim.now_s)
    assert event["kind"] == "health" and event["verdict"] in ("watch", "act")
    assert event["maintenance_due"] is True
    joints: list[dict[str, Any]] = event["joints"]  # type: ignore[assignment]
    assert [j["joint"] for j in joints] == [1, 2, 3, 4, 5, 6]
    assert set(joints[0]) == {"joint", "verdict", "reason", "life_used_percent"}
    answer = report_answer(ROBOT, report, queue_dropped=3)
    assert answer["robot"] == ROBOT and answer["verdict"] == event["verdict"]
    assert answer["dropped_frames"] == 3 + sim.engine.dropped_frames
    baseline: dict[str, Any] = answer["baseline"]  # type: ignore[assignment]
    assert baseline["created_by"] == "olivia" and baseline["active"] is True
    assert baseline["cycles"] == BASELINE_CYCLES and baseline["learned_to"] is not None
    snapshots = [snapshot_of(report, str(event["verdict"]))]
    assert trend_answer(ROBOT, snapshots)["points"][0]["joints"][0]["joint"] == 1  # type: ignore[index]
    rows = list(csv.DictReader(io.StringIO(report_csv(ROBOT, snapshots, 0.0, sim.now_s))))
    assert [row["joint"] for row in rows] == ["1", "2", "3", "4", "5", "6"]
    assert rows[0]["verdict"] == joints[0]["verdict"] and rows[0]["baseline_id"] == "1"


def test_an_advisory_alarm_is_shelved_at_most_seven_days() -> None:
    alarms = AlarmEngine(
        ROBOT,
        motor_temperature_c=80.0,
        motor_temperature_deadband_c=2.0,
        gap_rate_per_min=10.0,
        connection_delay_s=2.0,
        shelve_max_s=30 * 86_400.0,
        shelve_max_by_priority_s={"high": 3600.0, "medium": 3600.0, "low": 3600.0},
    )
    alarms.raised("health.2", active=True, message="J2: friction 9 % above", now_s=1.0)
    assert alarms.snapshot_of("health.2")["shelve_max_s"] == 7 * 86_400.0
    with pytest.raises(AlarmRefusedError, match="advisory priority's own maximum"):
        alarms.shelve(f"{ROBOT}:health.2", "olivia", "waiting for parts", 8 * 86_400.0)
    assert alarms.shelve(f"{ROBOT}:health.2", "olivia", "waiting for parts", 7 * 86_400.0)[
        "shelved"
    ]


def test_the_arm_setting_names_an_arm_of_the_table() -> None:
    assert HealthServiceSettings(health_arm="m0609").health_arm == "M0609"
    assert HealthServiceSettings().health_arm == ""  # from the robot's identity
    with pytest.raises(ValidationError, match="unknown arm 'X1'; choose one of M1013, M0609"):
        HealthServiceSettings(health_arm="X1")
