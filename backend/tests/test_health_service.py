"""Robot health in the running service (issue 40, docs/health.md "In the service") on the real
stack: the emulator runs its demo program and marks each cycle on a register, the service
measures the cycles and feeds every frame to the health engine off the cyclic path. A baseline
is asked for over REST (an operator's, audited; a viewer is refused), learned from the next
cycles, then wear is injected through the emulator's control API (``POST /wear``): the joint
reads watch or act, its advisory alarm comes, a ``health`` event says so; the trend and the
weekly report read the snapshots."""

from __future__ import annotations

import csv
import io
import re
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.emulator.robot import RobotSettings as SimulationSettings
from cobot_hmi.health import HealthSettings
from emulator_harness import FAST_TIMINGS, Emulator, running_emulator
from service_support import (
    OPERATOR,
    VIEWER,
    Running,
    eventually_async,
    running_service,
    service_settings,
)

pytestmark = pytest.mark.timeout(400)

ROBOT = "robot"
MARKER = 63
TRIGGER = f"bit_output_registers.{MARKER}:rising"
WORN_JOINT = 1
BASELINE_CYCLES = 3
WEAR_DEADLINE_S = 240.0
"""Until the worn joint reads watch: the baseline's cycles and about ten worn cycles of the
emulated program on a loaded machine."""


@pytest.fixture
async def emulator(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    # The motors' temperature held at the room's: the friction is compared within bands of
    # the motor's temperature, and a robot that warms through the test would leave the
    # baseline's band (docs/health.md "Friction"); a cold start is the engine's test's.
    settings = SimulationSettings(
        timings=FAST_TIMINGS,
        cycle_marker_register=MARKER,
        temperature_rise_at_rated_current_c=0.0,
    )
    async with running_emulator(robot_host, plc_host, settings) as running:
        yield running


def _settings(emulator: Emulator, robot_host: str, plc_host: str, state_dir: Path) -> Any:
    return service_settings(
        robot_host,
        emulator.target.tcp_port,
        plc_host,
        state_dir,
        cycle_trigger=TRIGGER,
        history=False,
        health_refresh_s=0.5,
        health_report_s=0.5,
        health_save_s=1.0,
        health_snapshot_s=1.0,
    )


async def _health(hmi: Running) -> dict[str, Any]:
    async with hmi.client() as client:
        answer = await client.get(f"/api/v1/robots/{ROBOT}/health")
    assert answer.status_code == 200, answer.text
    body: dict[str, Any] = answer.json()
    return body


async def _baseline(hmi: Running, token: str | None, **body: Any) -> Any:
    async with hmi.client(token) as client:
        return await client.post(f"/api/v1/robots/{ROBOT}/health/baselines", json=body)


async def test_the_report_answers_every_joint_and_a_restart_keeps_what_it_counted(
    emulator: Emulator, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = _settings(emulator, robot_host, plc_host, tmp_path)
    async with running_service(settings) as hmi:
        body = await _health(hmi)
        assert body["robot"] == ROBOT
        assert body["arm"] == "M1013"  # the emulator's identity names it
        assert [j["joint"] for j in body["joints"]] == [1, 2, 3, 4, 5, 6]
        assert {j["verdict"] for j in body["joints"]} == {"ok"}
        assert "no baseline yet" in body["joints"][0]["reason"]
        assert body["verdict"] == "ok" and body["maintenance_due"] is False
        assert body["baseline"] is None and body["learning"] is None

        async def frames_fed() -> bool:
            return hmi.service.health.monitors[ROBOT].frames_fed > 0

        await eventually_async(frames_fed, timeout_s=60.0)
        # Fed on the robot's clock: its frames' T→O sequence numbers at the granted API.
        assert hmi.service.health.monitors[ROBOT].clock.runs >= 1
        fed = re.search(r'^cobot_hmi_health_frames_fed_total\{robot="robot"\} (\S+)$',
                        await hmi.metrics(), re.MULTILINE)  # fmt: skip
        assert fed is not None and float(fed.group(1)) > 0
        async with hmi.client() as client:
            listed = await client.get(f"/api/v1/robots/{ROBOT}/health/baselines")
            unknown = await client.get("/api/v1/robots/nobody/health")
        assert listed.status_code == 200 and listed.json() == {"items": []}
        assert unknown.status_code == 404
        created = await _baseline(hmi, await hmi.login(OPERATOR), reason="first", cycles=500)
        assert created.status_code == 201, created.text
        before = await _health(hmi)
    # Stopped (the state saved), started again on the same database: what was counted stays,
    # and the baseline being learned goes on learning.
    async with running_service(settings) as hmi:
        after = await _health(hmi)
        assert after["learning"]["id"] == created.json()["id"]
        assert after["learning"]["reason"] == "first"
        for old, new in zip(before["joints"], after["joints"], strict=True):
            assert new["life_used_percent"] >= old["life_used_percent"]
        assert after["cycles"] >= before["cycles"]
        async with hmi.client() as client:
            listed = await client.get(f"/api/v1/robots/{ROBOT}/health/baselines")
        assert [(b["id"], b["learning"]) for b in listed.json()["items"]] == [(1, True)]


async def test_a_baseline_then_wear_reads_watch_with_its_advisory_alarm(
    emulator: Emulator, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    async with running_service(_settings(emulator, robot_host, plc_host, tmp_path)) as hmi:
        viewer, operator = await hmi.login(VIEWER), await hmi.login(OPERATOR)
        refused = await _baseline(hmi, viewer, reason="new reducer on J1", cycles=2)
        assert refused.status_code == 403, refused.text
        empty = await _baseline(hmi, operator, reason="  ", cycles=2)
        assert empty.status_code == 422, empty.text
        created = await _baseline(hmi, operator, reason="commissioned", cycles=BASELINE_CYCLES)
        assert created.status_code == 201, created.text
        baseline = created.json()
        assert baseline["created_by"] == OPERATOR[0] and baseline["reason"] == "commissioned"
        assert baseline["learning"] is True and baseline["active"] is False
        assert baseline["target_cycles"] == BASELINE_CYCLES and baseline["arm"] == "M1013"

        async with hmi.client(operator) as client:
            audit = (await client.get("/api/v1/audit", params={"q": "health"})).json()
        actions = [(row["action"], row["outcome"], row["user"]) for row in audit["items"]]
        assert ("health.baseline", "started", OPERATOR[0]) in actions
        assert ("health.baseline", "forbidden", VIEWER[0]) in actions

        async def learned() -> bool:
            return (await _health(hmi))["baseline"] is not None

        await eventually_async(learned, timeout_s=WEAR_DEADLINE_S)
        body = await _health(hmi)
        assert body["baseline"]["id"] == baseline["id"] and body["learning"] is None
        assert body["baseline"]["cycles"] == BASELINE_CYCLES

        worn = await emulator.api.post("/wear", json={"joint": WORN_JOINT, "friction_percent": 60})
        assert worn.status_code == 200, worn.text

        async def flagged() -> bool:
            joint = (await _health(hmi))["joints"][WORN_JOINT - 1]
            return bool(joint["verdict"] in ("watch", "act"))

        await eventually_async(flagged, timeout_s=WEAR_DEADLINE_S)
        body = await _health(hmi)
        joint = body["joints"][WORN_JOINT - 1]
        assert "friction" in joint["reason"]
        assert joint["friction_percent"] >= HealthSettings().friction_watch_percent
        assert body["maintenance_due"] is True and body["verdict"] in ("watch", "act")

        async def advised() -> bool:
            async with hmi.client() as client:
                alarms = (await client.get("/api/v1/alarms", params={"robot": ROBOT})).json()
            return any(a["key"] == f"health.{WORN_JOINT}" and a["active"] for a in alarms["items"])

        await eventually_async(advised, timeout_s=30.0)
        async with hmi.client() as client:
            alarms = (await client.get("/api/v1/alarms", params={"robot": ROBOT})).json()["items"]
            events = (
                await client.get("/api/v1/events", params={"robot": ROBOT, "kind": "health"})
            ).json()
            trend = (await client.get(f"/api/v1/robots/{ROBOT}/health/trend")).json()
            report = await client.get(f"/api/v1/robots/{ROBOT}/health/report.csv")
            listed = (await client.get(f"/api/v1/robots/{ROBOT}/health/baselines")).json()
        cycles = re.search(
            r'^cobot_hmi_health_cycles_fed_total\{robot="robot"\} (\S+)$',
            await hmi.metrics(),
            re.MULTILINE,
        )
        assert cycles is not None and float(cycles.group(1)) >= BASELINE_CYCLES
        (advisory,) = [a for a in alarms if a["key"] == f"health.{WORN_JOINT}"]
        assert advisory["priority"] == "advisory" and advisory["priority_rank"] == 4
        assert "friction" in advisory["message"]
        assert all(a["priority_rank"] < 4 for a in alarms if a["kind"] != "health")
        flagged_events = [
            e for e in events["items"] if e["joints"][WORN_JOINT - 1]["verdict"] != "ok"
        ]
        assert flagged_events, events
        assert trend["points"] and len(trend["points"][-1]["joints"]) == 6
        rows = list(csv.DictReader(io.StringIO(report.text)))
        assert report.status_code == 200 and rows and rows[0]["robot"] == ROBOT
        assert {row["joint"] for row in rows} == {"1", "2", "3", "4", "5", "6"}
        assert [(b["id"], b["active"]) for b in listed["items"]] == [(baseline["id"], True)]


async def test_a_baseline_without_cycles_and_health_off_are_refused(
    emulator: Emulator, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    settings = _settings(emulator, robot_host, plc_host, tmp_path).replace(cycle_trigger="")
    async with running_service(settings) as hmi:
        operator = await hmi.login(OPERATOR)
        refused = await _baseline(hmi, operator, reason="commissioned", cycles=5)
        assert refused.status_code == 409 and "cycle_trigger" in refused.text
        async with hmi.client(operator) as client:
            audit = (await client.get("/api/v1/audit", params={"q": "cycle_trigger"})).json()
        assert [(r["action"], r["outcome"]) for r in audit["items"]] == [
            ("health.baseline", "refused")
        ]
    async with running_service(settings.replace(health_enabled=False)) as hmi:
        async with hmi.client() as client:
            off = await client.get(f"/api/v1/robots/{ROBOT}/health")
        assert off.status_code == 409 and "health_enabled" in off.text
