"""A baseline learned from a period already recorded (issue 40, docs/health.md "In the service") on
the real stack: the emulator runs its demo program and marks each cycle on a register, the
service records every frame (history) and measures the cycles; once a few cycles are in, an
operator names the period that holds them (``from``, ``to``) and the baseline is learned from
its recording at once: active, listed with its period, audited, kept across a restart. A period
without recording or cycles is refused (409), a body naming both ways or half a period is a
422."""

from __future__ import annotations

import time
from collections.abc import AsyncIterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.emulator.robot import RobotSettings as SimulationSettings
from cobot_hmi.service.health.period import MIN_PERIOD_CYCLES
from emulator_harness import FAST_TIMINGS, Emulator, running_emulator
from service_support import (
    OPERATOR,
    VIEWER,
    Running,
    eventually,
    eventually_async,
    running_service,
    service_settings,
)

pytestmark = pytest.mark.timeout(400)

ROBOT = "robot"
MARKER = 63
TRIGGER = f"bit_output_registers.{MARKER}:rising"
PERIOD_CYCLES = MIN_PERIOD_CYCLES + 1
CYCLES_DEADLINE_S = 180.0
"""Until the period holds its cycles: the emulated program's cycles on a loaded machine."""


@pytest.fixture
async def emulator(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
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
        history=True,
        history_segment_s=2.0,
        history_flush_s=0.2,
        health_refresh_s=0.5,
        health_report_s=0.5,
        health_save_s=1.0,
    )


async def _post(hmi: Running, token: str, **body: Any) -> Any:
    async with hmi.client(token) as client:
        return await client.post(f"/api/v1/robots/{ROBOT}/health/baselines", json=body)


async def _whole_cycles(hmi: Running, since_s: float) -> list[dict[str, Any]]:
    async with hmi.client() as client:
        answer = await client.get(f"/api/v1/robots/{ROBOT}/cycles", params={"from": since_s})
    assert answer.status_code == 200, answer.text
    return [c for c in answer.json()["cycles"] if not c["interrupted"]]


async def test_a_period_baseline_is_learned_from_its_recording_and_adopted(
    emulator: Emulator, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    started_s = time.time()
    settings = _settings(emulator, robot_host, plc_host, tmp_path)
    async with running_service(settings) as hmi:
        operator, viewer = await hmi.login(OPERATOR), await hmi.login(VIEWER)

        async def recorded_cycles() -> bool:
            return len(await _whole_cycles(hmi, started_s)) >= PERIOD_CYCLES

        await eventually_async(recorded_cycles, timeout_s=CYCLES_DEADLINE_S)
        cycles = await _whole_cycles(hmi, started_s)
        from_s, to_s = started_s, max(c["end"] for c in cycles) + 0.5
        await eventually(lambda: time.time() > to_s, timeout_s=5.0)  # `to` not in the future
        from_iso = datetime.fromtimestamp(from_s, UTC).isoformat()

        both = await _post(hmi, operator, reason="r", cycles=3, **{"from": from_s, "to": to_s})
        half = await _post(hmi, operator, reason="r", **{"from": from_s})
        future = await _post(
            hmi, operator, reason="r", **{"from": from_s, "to": time.time() + 3600}
        )
        backwards = await _post(hmi, operator, reason="r", **{"from": to_s, "to": from_s})
        too_long = await _post(hmi, operator, reason="r", **{"from": to_s - 8 * 86_400, "to": to_s})
        wrong = [(both, "cycles"), (half, "to"), (future, "to"), (backwards, "from")]
        for answer, field in [*wrong, (too_long, "7 days")]:
            assert answer.status_code == 422, answer.text
            assert field in answer.text
        refused = await _post(hmi, viewer, reason="r", **{"from": from_s, "to": to_s})
        assert refused.status_code == 403, refused.text
        empty = await _post(
            hmi, operator, reason="nothing then", **{"from": from_s - 7200, "to": from_s - 3600}
        )
        assert empty.status_code == 409, empty.text
        assert "cycles" in empty.json()["detail"]["reason"]

        created = await _post(
            hmi, operator, reason="new reducer on J2", **{"from": from_iso, "to": to_s}
        )
        assert created.status_code == 201, created.text
        baseline = created.json()
        assert baseline["active"] is True and baseline["learning"] is False
        assert baseline["reason"] == "new reducer on J2" and baseline["created_by"] == OPERATOR[0]
        assert baseline["learned_from"] == pytest.approx(from_s, abs=1e-3)
        assert baseline["learned_to"] == pytest.approx(to_s)
        assert baseline["cycles"] == baseline["target_cycles"] >= MIN_PERIOD_CYCLES

        async with hmi.client(operator) as client:
            health = (await client.get(f"/api/v1/robots/{ROBOT}/health")).json()
            listed = (await client.get(f"/api/v1/robots/{ROBOT}/health/baselines")).json()
            audit = (await client.get("/api/v1/audit", params={"q": "health"})).json()
        assert health["baseline"]["id"] == baseline["id"] and health["learning"] is None
        (item,) = [b for b in listed["items"] if b["id"] == baseline["id"]]
        assert item["active"] is True
        assert item["learned_from"] == pytest.approx(from_s, abs=1e-3)
        assert item["learned_to"] == pytest.approx(to_s)
        rows = [(r["action"], r["outcome"], r["user"]) for r in audit["items"]]
        assert ("health.baseline", "saved", OPERATOR[0]) in rows
        assert ("health.baseline", "forbidden", VIEWER[0]) in rows
        (adopted,) = [r for r in audit["items"] if r["outcome"] == "saved"]
        assert "from the period" in adopted["summary"]
        assert adopted["reason"] == "new reducer on J2"
    # Kept: started again on the same database, the period's baseline is the one in use.
    async with running_service(settings) as hmi:
        async with hmi.client() as client:
            again = (await client.get(f"/api/v1/robots/{ROBOT}/health/baselines")).json()
        (kept,) = [b for b in again["items"] if b["id"] == baseline["id"]]
        assert kept["active"] is True and kept["reason"] == "new reducer on J2"
        assert kept["learned_from"] == pytest.approx(from_s, abs=1e-3)
        assert kept["learned_to"] == pytest.approx(to_s)
