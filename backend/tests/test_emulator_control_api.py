"""Issue 4: the emulator's control API over real HTTP on ``robot_host``: what ``GET /status``
shows, and that a bad request gets a 4xx with a reason while nothing changes."""

from __future__ import annotations

import asyncio
import signal
import sys
from collections.abc import AsyncIterator
from dataclasses import replace

import httpx
import pytest

from cobot_hmi.codec import frame_from_json
from cobot_hmi.emulator.robot.simulated import RobotSettings
from cobot_hmi.generated.frames import RobotState
from conftest import free_tcp_port
from emulator_harness import FAST_TIMINGS, Emulator, running_emulator

SETTABLE = ("controlbox_di", "tool_di", "analog_input_type")


@pytest.fixture
async def emulator(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    async with running_emulator(robot_host, plc_host) as emulator:
        yield emulator


@pytest.fixture
async def initializing(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    """An emulator whose robot stays INITIALIZING for the whole test (the harness's 0.4 s ran
    out before the first request on a machine at load 30)."""
    timings = replace(FAST_TIMINGS, initializing_s=3600.0)
    async with running_emulator(robot_host, plc_host, RobotSettings(timings=timings)) as emulator:
        yield emulator


async def snapshot(emulator: Emulator) -> dict[str, object]:
    """What a refused request must leave as it was."""
    status = (await emulator.api.get("/status")).json()
    robot = dict(status["robot"])
    robot.pop("program_step")
    robot.pop("program_cycles_completed")
    robot.pop("part_present")
    frame = status["frame"]
    return {
        "robot": robot,
        "faults": status["faults"],
        # DI 1 follows the program (part present): only the settable inputs must keep still.
        "frame": {
            **{name: frame[name] for name in SETTABLE},
            "controlbox_di": frame["controlbox_di"][1:],
        },
    }


async def test_status_shows_the_frame_the_robot_and_the_emulator(initializing: Emulator) -> None:
    emulator = initializing
    response = await emulator.api.get("/status")
    assert response.status_code == 200
    status = response.json()
    assert set(status) >= {"frame", "robot", "connections", "faults", "plc_command"}
    frame = frame_from_json(status["frame"])  # the decoded frame, in the canonical JSON form
    assert frame.robot_state == RobotState.INITIALIZING
    assert status["frame"]["robot_state_name"] == "INITIALIZING"
    assert status["robot"]["model"] == "M1013"
    assert status["connections"] == []
    assert status["faults"] == {
        "t2o_drop_percent": 0.0,
        "t2o_delay_ms": 0.0,
        "t2o_interval_factor": 1.0,
        "t2o_silent": False,
        "t2o_corrupt_count": 0,
        "refuse_next_forward_open": None,
    }
    assert status["plc_command"]["controlbox_do"] == [False] * 16


BAD_REQUESTS = [
    ("/estop", b'{"now": true}', 422, "no fields"),
    ("/teach-button", b"", 400, "JSON object"),
    ("/teach-button", b"pressed", 400, "not JSON"),
    ("/teach-button", b"[true]", 400, "JSON object"),
    ("/teach-button", b"{}", 422, "missing"),
    ("/teach-button", b'{"pressed": "yes"}', 422, "true or false"),
    ("/teach-button", b'{"pressed": true, "hard": true}', 422, "unknown field"),
    ("/power-button", b'{"pressed": 1}', 422, "true or false"),
    ("/program", b'{"run": true}', 422, "unknown field"),
    ("/state", b'{"robot_state": 256}', 422, "outside"),
    ("/state", b'{"robot_state": -1}', 422, "outside"),
    ("/state", b'{"robot_state": 1.5}', 422, "integer"),
    ("/state", b'{"robot_state": true}', 422, "integer"),
    ("/joints", b'{"joint_position": [0, 0, 0]}', 422, "expected 6"),
    ("/joints", b'{"joint_position": [0, 0, 161, 0, 0, 0]}', 422, "limits"),
    ("/joints", b'{"joint_position": [0, 0, 0, 0, 0, "x"]}', 422, "number"),
    ("/joints", b'{"joint_position": 5}', 422, "array"),
    ("/inputs", b"{}", 422, "at least one"),
    ("/inputs", b'{"controlbox_di": {"0": true}}', 422, "follows the program"),
    ("/inputs", b'{"tool_di": {"1": true}, "controlbox_di": {"16": true}}', 422, "out of range"),
    ("/inputs", b'{"tool_di": {"1": true}, "analog_input": {"0": "high"}}', 422, "number"),
    ("/inputs", b'{"tool_di": {"1": true}, "analog_input_type": {"0": 2}}', 422, "0 to 1"),
    ("/inputs", b'{"controlbox_do": {"1": true}}', 422, "cannot be set"),
    ("/faults", b"{}", 422, "at least one"),
    ("/faults", b'{"t2o_drop_percent": 101}', 422, "outside"),
    ("/faults", b'{"t2o_drop_percent": 10, "t2o_delay_ms": -1}', 422, "outside"),
    ("/faults", b'{"t2o_delay_ms": 5, "t2o_silent": "on"}', 422, "true or false"),
    ("/faults", b'{"t2o_silent": true, "t2o_corrupt_count": 2.5}', 422, "integer"),
    ("/faults", b'{"t2o_corrupt_count": 1, "refuse_next_forward_open": 0}', 422, "outside"),
    ("/faults", b'{"refuse_next_forward_open": "0xZZ"}', 422, "hex"),
    ("/faults", b'{"drop_sessions": true, "explode": true}', 422, "unknown field"),
    ("/tool-offset", b'{"position": [0, 0], "orientation": [0, 0, 0]}', 422, "expected 3"),
    ("/collaborative", b'{"enabled": null}', 422, "true or false"),
]


async def test_bad_requests_get_a_reason_and_change_nothing(emulator: Emulator) -> None:
    # One emulator for every case (starting one per case would cost more than the checks),
    # once it has settled: running its program, a state that lasts.
    for _ in range(1000):
        if (await emulator.api.get("/status")).json()["robot"]["program_running"]:
            break
        await asyncio.sleep(0.01)
    for path, body, status, reason in BAD_REQUESTS:
        case = f"POST {path} {body!r}"
        before = await snapshot(emulator)
        response = await emulator.api.post(
            path, content=body, headers={"content-type": "application/json"}
        )
        assert response.status_code == status, f"{case}: {response.text}"
        assert reason in response.json()["detail"]["reason"], f"{case}: {response.text}"
        assert await snapshot(emulator) == before, f"{case} changed something"


async def test_commands_refused_in_the_wrong_state_get_409_and_change_nothing(
    initializing: Emulator,
) -> None:
    emulator = initializing
    # INITIALIZING at first: nothing to reset, no protective stop with the servo off.
    before = await snapshot(emulator)
    for path in ("/reset", "/protective-stop"):
        response = await emulator.api.post(path, json={})
        assert response.status_code == 409, response.text
        assert response.json()["detail"]["reason"]
    assert await snapshot(emulator) == before
    await emulator.post("/estop")
    before = await snapshot(emulator)
    response = await emulator.api.post("/program", json={"running": True})
    assert response.status_code == 409
    assert "reset first" in response.json()["detail"]["reason"]
    assert await snapshot(emulator) == before


async def test_valid_commands_answer_the_robot_view(emulator: Emulator) -> None:
    answer = await emulator.post("/estop")
    robot = answer["robot"]
    assert isinstance(robot, dict)
    assert robot["robot_state"] == RobotState.EMERGENCY_STOP
    assert robot["robot_state_name"] == "EMERGENCY_STOP"
    answer = await emulator.post("/faults", {"t2o_delay_ms": 2.5, "refuse_next_forward_open": 262})
    assert answer["faults"] == {
        "t2o_drop_percent": 0.0,
        "t2o_delay_ms": 2.5,
        "t2o_interval_factor": 1.0,
        "t2o_silent": False,
        "t2o_corrupt_count": 0,
        "refuse_next_forward_open": 262,
    }
    assert emulator.target.faults.refuse_next_forward_open == 0x0106
    await emulator.post("/faults/clear")
    assert emulator.target.faults.t2o_delay_ms == 0.0
    answer = await emulator.post(
        "/tool-offset", {"position": [0, 0, 100], "orientation": [0, 0, 0]}
    )
    frame = (await emulator.api.get("/status")).json()["frame"]
    assert frame["tool_offset_position"] == [0.0, 0.0, 100.0]


async def test_the_emulator_verb_serves_the_control_api(robot_host: str) -> None:
    """``cobot-hmi emulator`` as a user runs it: the simulated robot and its control API."""
    control_port = free_tcp_port(robot_host)
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "emulator",
        "--host",
        robot_host,
        "--tcp-port",
        str(free_tcp_port(robot_host)),
        "--control-port",
        str(control_port),
        "--model",
        "M0609",
        "--kinematic-refresh-ms",
        "100",
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        assert process.stdout is not None
        # A process's start (imports, the target, the API) on a machine at load 30 took over 20 s.
        banner = await asyncio.wait_for(process.stdout.readline(), 90)
        assert f"control API http://{robot_host}:{control_port}".encode() in banner
        async with httpx.AsyncClient(base_url=f"http://{robot_host}:{control_port}") as api:
            status = (await api.get("/status")).json()
            assert status["robot"]["model"] == "M0609"
            assert status["robot"]["kinematic_refresh_ms"] == 100.0
            answer = await api.post("/estop", json={})
            assert answer.json()["robot"]["robot_state_name"] == "EMERGENCY_STOP"
    finally:
        if process.returncode is None:
            process.send_signal(signal.SIGTERM)
        code = await asyncio.wait_for(process.wait(), 60)
        await process.communicate()
    assert code == 0
