"""Issue 4: every state transition with its flags, and the robot's I/O, observed through the real
EtherNet/IP connection: our scanner (the originator) on ``plc_host`` holds a class 1 connection
to the emulator on ``robot_host``; scenarios are driven through the emulator's control API."""

from __future__ import annotations

import socket
from collections.abc import AsyncIterator

import pytest

from cobot_hmi.codec import command_from_json
from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.emulator.robot import RobotSettings
from cobot_hmi.generated.frames import Frame, RobotState
from cobot_hmi.layout import ROBOT_STATES, RobotStateInfo
from cobot_hmi.scanner.originator import Originator, OriginatorSettings
from emulator_harness import (
    FAST_TIMINGS,
    Emulator,
    flags,
    observe,
    running_emulator,
)
from waiting import eventually

S = RobotState
SERVO = flags(servo_on=True)


@pytest.fixture
async def emulator(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    async with running_emulator(robot_host, plc_host) as emulator:
        yield emulator


async def running(emulator: Emulator) -> Frame:
    if emulator.originator is None:
        await emulator.connect()
    return await emulator.frame_where(lambda f: f.robot_state == S.STANDALONE_RUNNING)


def since(emulator: Emulator, mark: int) -> list[tuple[int, tuple[bool, ...]]]:
    return emulator.observed[mark:]


async def test_start_initializing_then_standby_with_servo_then_running(emulator: Emulator) -> None:
    await emulator.connect()
    moving = await emulator.frame_where(
        lambda f: f.robot_state == S.STANDALONE_RUNNING and any(f.joint_velocity)
    )
    assert emulator.observed == [
        (S.INITIALIZING, flags()),
        (S.STANDALONE_STANDBY, SERVO),
        (S.STANDALONE_RUNNING, SERVO),
    ]
    assert moving.controller_version == (2, 12, 1)


async def test_emergency_stop_then_reset_through_safe_off(emulator: Emulator) -> None:
    await running(emulator)
    mark = len(emulator.observed)
    await emulator.post("/estop")
    stopped = await emulator.frame_where(lambda f: f.robot_state == S.EMERGENCY_STOP)
    assert observe(stopped) == (S.EMERGENCY_STOP, flags(emergency_stopped=True))
    assert stopped.joint_velocity == (0.0,) * 6
    held = (await emulator.frame_where(lambda f: True)).joint_position
    assert held == stopped.joint_position, "motion stopped at once"
    await emulator.post("/program", {"running": True}, expect=409)
    await emulator.post("/reset")
    await emulator.frame_where(lambda f: f.robot_state == S.STANDALONE_STANDBY)
    assert since(emulator, mark) == [
        (S.EMERGENCY_STOP, flags(emergency_stopped=True)),
        (S.SAFE_OFF, flags()),
        (S.STANDALONE_STANDBY, SERVO),
    ]
    await emulator.post("/program", {"running": True})
    await emulator.frame_where(
        lambda f: f.robot_state == S.STANDALONE_RUNNING and any(f.joint_velocity)
    )


async def test_protective_stop_gives_interrupted_with_safety_stopped(emulator: Emulator) -> None:
    await running(emulator)
    mark = len(emulator.observed)
    await emulator.post("/protective-stop")
    frame = await emulator.frame_where(lambda f: f.robot_state == S.INTERRUPTED)
    assert frame.joint_velocity == (0.0,) * 6
    await emulator.post("/reset")
    await emulator.frame_where(lambda f: f.robot_state == S.STANDALONE_STANDBY)
    assert since(emulator, mark) == [
        (S.INTERRUPTED, flags(servo_on=True, safety_stopped=True)),
        (S.SAFE_OFF, flags()),
        (S.STANDALONE_STANDBY, SERVO),
    ]


async def test_teach_button_gives_hand_guiding_with_its_flag(emulator: Emulator) -> None:
    await running(emulator)
    mark = len(emulator.observed)
    await emulator.post("/teach-button", {"pressed": True})
    await emulator.frame_where(lambda f: f.robot_state == S.MANUAL_HANDGUIDING)
    await emulator.post("/teach-button", {"pressed": False})
    await emulator.frame_where(lambda f: f.robot_state == S.STANDALONE_STANDBY)
    assert since(emulator, mark) == [
        (S.MANUAL_HANDGUIDING, flags(servo_on=True, direct_teach_button_pressed=True)),
        (S.STANDALONE_STANDBY, SERVO),
    ]


async def test_power_button_flag(emulator: Emulator) -> None:
    await running(emulator)
    await emulator.post("/power-button", {"pressed": True})
    frame = await emulator.frame_where(lambda f: f.power_button_pressed)
    assert observe(frame) == (S.STANDALONE_RUNNING, flags(servo_on=True, power_button_pressed=True))
    await emulator.post("/power-button", {"pressed": False})
    await emulator.frame_where(lambda f: not f.power_button_pressed)


async def test_collaborative_mode_gives_the_collaborative_states(emulator: Emulator) -> None:
    await running(emulator)
    mark = len(emulator.observed)
    await emulator.post("/collaborative", {"enabled": True})
    await emulator.frame_where(lambda f: f.robot_state == S.COLLABORATIVE_RUNNING)
    await emulator.post("/program", {"running": False})
    await emulator.frame_where(lambda f: f.robot_state == S.COLLABORATIVE_STANDBY)
    await emulator.post("/collaborative", {"enabled": False})
    await emulator.frame_where(lambda f: f.robot_state == S.STANDALONE_STANDBY)
    assert since(emulator, mark) == [
        (S.COLLABORATIVE_RUNNING, SERVO),
        (S.COLLABORATIVE_STANDBY, SERVO),
        (S.STANDALONE_STANDBY, SERVO),
    ]


async def test_program_stop_and_start(emulator: Emulator) -> None:
    await running(emulator)
    await emulator.post("/program", {"running": False})
    stopped = await emulator.frame_where(lambda f: f.robot_state == S.STANDALONE_STANDBY)
    assert stopped.joint_velocity == (0.0,) * 6
    await emulator.post("/program", {"running": True})
    await emulator.frame_where(
        lambda f: f.robot_state == S.STANDALONE_RUNNING and any(f.joint_velocity)
    )


async def test_every_state_can_be_forced(emulator: Emulator) -> None:
    await running(emulator)
    for info in ROBOT_STATES:
        await emulator.post("/state", {"robot_state": info.value})
        frame = await emulator.frame_where(
            lambda f, info=info: f.robot_state == info.value  # type: ignore[misc]
        )
        assert frame.emergency_stopped == (info.value == S.EMERGENCY_STOP)
        assert frame.safety_stopped == (info.value == S.INTERRUPTED)
    await emulator.post("/state", {"robot_state": 99})
    await emulator.frame_where(lambda f: f.robot_state == 99)  # shown as unknown, never an error
    await emulator.post("/reset")
    await emulator.frame_where(lambda f: f.robot_state == S.STANDALONE_STANDBY)


async def test_joints_stop_the_program_and_hold_the_arm(emulator: Emulator) -> None:
    await running(emulator)
    target = [10.0, -20.0, 45.0, 30.0, -60.0, 90.0]
    await emulator.post("/joints", {"joint_position": target})
    frame = await emulator.frame_where(lambda f: list(f.joint_position) == pytest.approx(target))
    assert frame.robot_state == S.STANDALONE_STANDBY
    assert frame.joint_velocity == (0.0,) * 6
    later = await emulator.frame_where(lambda f: True)
    assert list(later.joint_position) == pytest.approx(target)


async def test_inputs_reach_the_frame(emulator: Emulator) -> None:
    await running(emulator)
    await emulator.post(
        "/inputs",
        {
            "controlbox_di": {"4": True, "15": True},
            "tool_di": {"2": True},
            "analog_input": {"1": 7.25},
            "analog_input_type": {"1": 1},
        },
    )
    frame = await emulator.frame_where(lambda f: f.controlbox_di[4])
    assert frame.controlbox_di[15]
    assert frame.tool_di == (False, False, True, False, False, False)
    assert frame.analog_input_type == (0, 1)
    assert frame.analog_input[1] == pytest.approx(7.25, abs=0.05)


async def test_di_1_follows_the_program(robot_host: str, plc_host: str) -> None:
    fast = RobotSettings(timings=FAST_TIMINGS, speed_fraction=1.0, accel_fraction=1.0)
    async with running_emulator(robot_host, plc_host, fast) as emulator:
        await running(emulator)
        await emulator.frame_where(lambda f: f.controlbox_di[0], timeout_s=30)
        await emulator.frame_where(lambda f: not f.controlbox_di[0], timeout_s=30)


async def test_outputs_follow_the_plc_while_in_run_and_hold_when_idle(emulator: Emulator) -> None:
    originator = await emulator.connect(
        timeout_multiplier=5
    )  # 1.28 s: a loaded run timed out at 160 ms
    assert await originator.wait_connected(10)
    command = command_from_json(
        {
            "controlbox_do": {"0": True, "7": True},
            "tool_do": {"5": True},
            "analog_output_type": {"1": 1},
            "analog_output": {"0": 12.0, "1": 5.5},
            "bit_input_registers": {"3": True, "40": True},
        },
        base=originator.command,
    )
    idle_frame = await emulator.frame_where(lambda f: True)
    originator.set_command(command)  # idle: the robot ignores it
    await originator.wait_sent(originator.packets_out + 3, 5)
    assert (await emulator.frame_where(lambda f: True)).controlbox_do == idle_frame.controlbox_do
    originator.set_run(True)
    frame = await emulator.frame_where(lambda f: f.controlbox_do[0])
    assert frame.controlbox_do == command.controlbox_do
    assert frame.tool_do == command.tool_do
    assert frame.analog_output_type == (0, 1)
    assert frame.analog_output == (12.0, 5.5)
    assert [n for n, bit in enumerate(frame.bit_output_registers) if bit] == [3, 40]
    status = (await emulator.api.get("/status")).json()
    assert status["plc_command"]["controlbox_do"][7] is True
    assert status["robot"]["outputs_owned_in_run"] is True
    assert [c["kind"] for c in status["connections"]] == ["owner"]
    originator.set_run(False)  # idle: the default idle behaviour holds the outputs
    await eventually(lambda: not emulator.robot.status()["outputs_owned_in_run"])
    held = await emulator.frame_where(lambda f: True)
    assert held.controlbox_do == command.controlbox_do
    assert held.analog_output == (12.0, 5.5)


def test_state_table_is_complete() -> None:
    assert [info.value for info in ROBOT_STATES] == list(range(21))
    assert all(isinstance(info, RobotStateInfo) for info in ROBOT_STATES)


def free_udp_port(host: str) -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


async def test_idle_behaviour_clear_when_the_owner_goes_idle_or_closes(
    robot_host: str, plc_host: str
) -> None:
    settings = RobotSettings(timings=FAST_TIMINGS, idle_behaviour=IdleBehaviour.CLEAR)
    async with running_emulator(robot_host, plc_host, settings) as emulator:
        owner = await emulator.connect()
        assert await owner.wait_connected(10)
        command = command_from_json(
            {"controlbox_do": {"2": True}, "analog_output": {"0": 9.0}}, base=owner.command
        )
        owner.set_command(command)
        owner.set_run(True)
        await emulator.frame_where(lambda f: f.controlbox_do[2])
        # A second scanner that never owns the outputs watches what the robot does.
        observer = Originator(
            OriginatorSettings(
                robot_host=robot_host,
                tcp_port=emulator.target.tcp_port,
                local_host=plc_host,
                input_only=True,
                request_t2o_port=free_udp_port(plc_host),
            )
        )
        await observer.start()
        try:
            assert await observer.wait_connected(10)
            await eventually(lambda: observer_frame(observer).controlbox_do[2])
            owner.set_run(False)  # the owner goes idle: the outputs clear
            await eventually(lambda: not observer_frame(observer).controlbox_do[2])
            assert observer_frame(observer).analog_output == (0.0, 0.0)
            owner.set_run(True)
            await eventually(lambda: observer_frame(observer).controlbox_do[2])
            await owner.stop()  # Forward Close: the outputs clear again
            await eventually(lambda: not observer_frame(observer).controlbox_do[2])
            assert emulator.robot.command_image() == command  # what the PLC last commanded
        finally:
            await observer.stop()


def observer_frame(observer: Originator) -> Frame:
    assert observer.latest is not None
    return observer.latest[0]
