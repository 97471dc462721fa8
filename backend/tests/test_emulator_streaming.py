"""The emulator as its verb runs it (monitoring values refreshed every 100 ms): its T→O a periodic
stream of the pump, which the class 1 engine reads the robot for only when the robot's frame
changes by itself (``SimulatedRobot.frame_still_until_s``), or at once after a command, a control
action or a fault. Seen from the scanner's side over real sockets on loopback."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator

import pytest

from cobot_hmi.emulator.robot import RobotSettings
from cobot_hmi.generated.frames import Frame, RobotState
from emulator_harness import DEADLINE_S, FAST_TIMINGS, Emulator, running_emulator
from waiting import eventually

MARKER = 63


@pytest.fixture
async def emulator(robot_host: str, plc_host: str) -> AsyncIterator[Emulator]:
    settings = RobotSettings(
        timings=FAST_TIMINGS, kinematic_refresh_ms=100.0, cycle_marker_register=MARKER
    )
    async with running_emulator(robot_host, plc_host, settings) as emulator:
        originator = await emulator.connect()
        assert await originator.wait_connected(DEADLINE_S)
        yield emulator


def streamed(emulator: Emulator) -> bool:
    return all(c.t2o_streaming for c in emulator.target.io.table())


async def frames_more(emulator: Emulator, count: int) -> None:
    originator = emulator.originator
    assert originator is not None
    target = originator.frames + count
    await eventually(lambda: originator.frames >= target)


def running(frame: Frame) -> bool:
    return frame.robot_state == RobotState.STANDALONE_RUNNING


async def test_the_stream_follows_the_robot_refreshes_steps_and_commands(
    emulator: Emulator,
) -> None:
    first = await emulator.frame_where(running)
    await eventually(lambda: streamed(emulator))
    # Monitoring refreshes (the arm moves), and the program's steps: the cycle marker's edges.
    await emulator.frame_where(lambda f: f.joint_position != first.joint_position)
    await emulator.frame_where(lambda f: not f.bit_output_registers[MARKER])
    await emulator.frame_where(lambda f: f.bit_output_registers[MARKER])
    await emulator.frame_where(lambda f: not f.bit_output_registers[MARKER])
    # A control action is in T→O without waiting for the robot's next change of its own.
    await emulator.post("/estop")
    stopped = await emulator.frame_where(lambda f: f.robot_state == RobotState.EMERGENCY_STOP)
    assert stopped.emergency_stopped and not stopped.servo_on
    # The timed SAFE_OFF → standby after a reset comes by itself.
    await emulator.post("/reset")
    await emulator.frame_where(lambda f: f.robot_state == RobotState.SAFE_OFF)
    await emulator.frame_where(lambda f: f.robot_state == RobotState.STANDALONE_STANDBY)
    await emulator.post("/program", {"running": True})
    await emulator.frame_where(running)
    originator = emulator.originator
    assert originator is not None
    assert originator.gaps == 0


async def test_a_fault_set_while_streaming_takes_over_at_once(emulator: Emulator) -> None:
    await emulator.frame_where(running)
    await eventually(lambda: streamed(emulator))
    io = emulator.target.io
    originator = emulator.originator
    assert originator is not None
    for _ in range(4):  # the robot's next change is up to 100 ms away: where it lands varies
        await emulator.post("/faults", {"t2o_delay_ms": 1})
        # Packet by packet now, and the next wake-up within the queue just built (one wake
        # period), not at the robot's next change of its own: the pump would run out of packets.
        assert not any(c.t2o_streaming for c in io.table())
        wake_period_s = io._wake_period_s
        assert wake_period_s is not None
        assert io._tick_due <= asyncio.get_running_loop().time() + wake_period_s
        await frames_more(emulator, 10)
        await emulator.post("/faults/clear")
        await eventually(lambda: streamed(emulator))
        await frames_more(emulator, 10)
    assert originator.gaps == 0
