"""The emulator's wear (issue 40, docs/emulator.md "Wear") on a real emulator over HTTP: wear
set, shown and cleared through the control API; a collision's external-torque spike and
protective stop in the frame; a hot motor in the frames' temperatures; bad entries refused with
422 and nothing changed; the wear clock's time factor; ``cobot-hmi emulator --wear FILE``
starting with a scenario, and refusing a bad one by name."""

from __future__ import annotations

import asyncio
import json
import sys
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from cobot_hmi.emulator.robot import RobotSettings
from cobot_hmi.emulator.robot.wear import JointWear, Wear
from cobot_hmi.generated.frames import RobotState
from conftest import free_tcp_port
from emulator_harness import FAST_TIMINGS, Emulator, running_emulator
from waiting import eventually_async


@pytest.fixture
async def emulator(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    async with running_emulator(robot_host, plc_host) as emulator:
        yield emulator


async def test_wear_is_set_shown_and_cleared(emulator: Emulator) -> None:
    response = await emulator.api.post("/wear", json={"joint": 3, "friction_percent": 25})
    assert response.status_code == 200, response.text
    wear = response.json()["robot"]["wear"]
    assert wear["joints"] == [
        {
            "joint": 3,
            "friction_percent": 25.0,
            "coulomb_nm": 0.0,
            "viscous_nm_s_deg": 0.0,
            "cold_friction_percent": 0.0,
            "hot_c": 0.0,
            "backlash_deg": 0.0,
            "ramp_s": 0.0,
            "level": 1.0,
        }
    ]
    response = await emulator.api.post("/wear", json={"time_factor": 1000})
    assert response.json()["robot"]["wear"]["time_factor"] == 1000.0
    response = await emulator.api.post("/wear/clear", json={})
    assert response.status_code == 200
    assert response.json()["robot"]["wear"]["joints"] == []


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"joint": 7, "friction_percent": 10}, "joint"),
        ({"joint": 0, "friction_percent": 10}, "joint"),
        ({"joint": 3, "friction_percent": "lots"}, "friction_percent"),
        ({"joint": 3, "grease": 1}, "grease"),
        ({"joint": 3, "hot_c": 1e9}, "hot_c"),
        ({"time_factor": 0.5}, "time_factor"),
        ({"collision_nm": 60}, "collision_nm"),
        ({"joint": 2, "collision_nm": 60, "hot_c": 5}, "collision_nm"),
    ],
)
async def test_bad_wear_is_refused_and_changes_nothing(
    emulator: Emulator, body: dict[str, object], field: str
) -> None:
    response = await emulator.api.post("/wear", json=body)
    assert response.status_code == 422, response.text
    assert response.json()["detail"]["field"] == field
    status = (await emulator.api.get("/status")).json()
    assert status["robot"]["model"] == "M1013"
    view = (await emulator.api.post("/wear", json={"time_factor": 1})).json()["robot"]["wear"]
    assert view == {"time_factor": 1.0, "joints": []}


async def _frame(emulator: Emulator) -> dict[str, Any]:
    frame: dict[str, Any] = (await emulator.api.get("/status")).json()["frame"]
    return frame


async def test_a_collision_shows_its_spike_and_a_protective_stop(emulator: Emulator) -> None:
    async def running() -> bool:
        return bool((await _frame(emulator))["robot_state"] == RobotState.STANDALONE_RUNNING)

    await eventually_async(running)
    response = await emulator.api.post("/wear", json={"joint": 2, "collision_nm": 60})
    assert response.status_code == 200, response.text
    frame = await _frame(emulator)
    assert frame["robot_state"] == RobotState.INTERRUPTED
    assert frame["joint_external_torque"][1] == pytest.approx(60.0, abs=2.0)
    assert abs(frame["joint_external_torque"][0]) < 2.0


async def test_a_hot_motor_runs_hotter_than_its_twin(robot_host: str, plc_host: str) -> None:
    # A short thermal time constant, so the motor settles in seconds rather than minutes.
    settings = RobotSettings(timings=FAST_TIMINGS, thermal_time_constant_s=0.2)
    async with running_emulator(robot_host, plc_host, settings) as emulator:
        before = (await _frame(emulator))["joint_motor_temperature"]
        response = await emulator.api.post("/wear", json={"joint": 5, "hot_c": 20})
        assert response.status_code == 200, response.text

        async def hot() -> bool:
            temperatures = (await _frame(emulator))["joint_motor_temperature"]
            return bool(temperatures[4] > before[4] + 15.0)

        await eventually_async(hot)
        temperatures = (await _frame(emulator))["joint_motor_temperature"]
        assert temperatures[5] == pytest.approx(before[5], abs=3.0)  # J6 stays as it was
        await emulator.api.post("/wear/clear", json={})

        async def cooled() -> bool:
            temperatures = (await _frame(emulator))["joint_motor_temperature"]
            return bool(temperatures[4] < before[4] + 3.0)

        await eventually_async(cooled)


def test_a_week_of_wear_grows_in_minutes_with_the_time_factor() -> None:
    wear = Wear(6)
    wear.set(2, JointWear(friction_percent=20.0, ramp_s=7 * 86_400.0), now_s=100.0)
    assert wear.level(2, 100.0 + 3600.0) == pytest.approx(3600.0 / (7 * 86_400.0))
    wear.set_time_factor(1000.0, now_s=100.0 + 3600.0)  # what ran before keeps its time
    week_in_s = 7 * 86_400.0 / 1000.0
    assert wear.level(2, 100.0 + 3600.0 + week_in_s / 2) == pytest.approx(
        0.5 + 3600.0 / 604_800.0, rel=1e-6
    )
    assert wear.level(2, 100.0 + 3600.0 + week_in_s) == 1.0
    viscous, coulomb = wear.friction_coefficients(2, 50.0, 0.05, 100.0 + 3600.0 + week_in_s)
    assert viscous == pytest.approx(0.01)  # +20 % of 0.05 N·m per °/s
    assert coulomb == 0.0


async def _emulator_process(host: str, *args: str) -> asyncio.subprocess.Process:
    return await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "emulator",
        "--host",
        host,
        "--tcp-port",
        str(free_tcp_port(host)),
        *args,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.STDOUT,
    )


async def test_the_emulator_starts_with_a_wear_scenario_file(
    robot_host: str, tmp_path: Path
) -> None:
    scenario = tmp_path / "wear.json"
    scenario.write_text(
        json.dumps(
            {
                "time_factor": 1000,
                "wear": [
                    {"joint": 3, "friction_percent": 25, "ramp_h": 168},
                    {"joint": 2, "hot_c": 8},
                ],
            }
        )
    )
    port = free_tcp_port(robot_host)
    process = await _emulator_process(
        robot_host, "--control-port", str(port), "--wear", str(scenario)
    )
    try:
        assert process.stdout is not None
        banner = await asyncio.wait_for(process.stdout.readline(), 20)
        assert b"control API" in banner, banner
        async with httpx.AsyncClient(base_url=f"http://{robot_host}:{port}") as api:
            wear = (await api.get("/status")).json()["wear"]
        assert wear["time_factor"] == 1000.0
        assert [(j["joint"], j["friction_percent"], j["hot_c"]) for j in wear["joints"]] == [
            (2, 0.0, 8.0),
            (3, 25.0, 0.0),
        ]
        assert wear["joints"][1]["ramp_s"] == 168 * 3600.0
        assert 0.0 < wear["joints"][1]["level"] < 1.0  # a week at 1000×: about 10 minutes
    finally:
        if process.returncode is None:
            process.terminate()
        await process.wait()


async def test_a_bad_wear_scenario_file_is_refused_by_name(robot_host: str, tmp_path: Path) -> None:
    scenario = tmp_path / "wear.json"
    scenario.write_text(json.dumps({"wear": [{"joint": 9, "friction_percent": 25}]}))
    process = await _emulator_process(robot_host, "--wear", str(scenario))
    output, _ = await asyncio.wait_for(process.communicate(), 30)
    assert process.returncode == 2
    assert b"wear[0]: joint: expected an integer 1" in output
