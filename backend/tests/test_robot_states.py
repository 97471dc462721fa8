"""The simulated robot's state machine, flags and I/O, at model level (no sockets).

The same transitions are observed through a real EtherNet/IP connection in
``test_emulator_scenarios.py``.
"""

from __future__ import annotations

import pytest

from cobot_hmi.codec import zero_command
from cobot_hmi.emulator.robot import (
    IdleBehaviour,
    RobotCommandError,
    RobotSettings,
    SimulatedRobot,
    StateTimings,
)
from cobot_hmi.emulator.robot.robot_io import parse_register_map
from cobot_hmi.generated.frames import Frame, RobotState
from cobot_hmi.layout import ROBOT_STATES, flag_fields

TIMINGS = StateTimings(initializing_s=1.0, program_start_delay_s=0.5, safe_off_s=0.3)


def robot(**changes: object) -> SimulatedRobot:
    settings = RobotSettings(timings=TIMINGS)
    for name, value in changes.items():
        setattr(settings, name, value)
    return SimulatedRobot(settings, start_s=0.0)


def flags(frame: Frame) -> dict[str, bool]:
    return {f.name: getattr(frame, f.name) for f in flag_fields()}


def only(**set_flags: bool) -> dict[str, bool]:
    return {f.name: set_flags.get(f.name, False) for f in flag_fields()}


def test_start_initializing_then_standby_then_running() -> None:
    r = robot()
    first = r.produce_frame(0.0)
    assert first.robot_state == RobotState.INITIALIZING
    assert flags(first) == only()
    standby = r.produce_frame(1.2)
    assert standby.robot_state == RobotState.STANDALONE_STANDBY
    assert flags(standby) == only(servo_on=True)
    assert standby.joint_velocity == (0.0,) * 6
    running = r.produce_frame(1.7)
    assert running.robot_state == RobotState.STANDALONE_RUNNING
    assert flags(running) == only(servo_on=True)
    assert any(r.produce_frame(2.0).joint_velocity)


def test_emergency_stop_stops_at_once_and_reset_goes_through_safe_off() -> None:
    r = robot()
    moving = r.produce_frame(2.0)
    assert any(moving.joint_velocity)
    r.estop(2.0)
    stopped = r.produce_frame(2.0)
    assert stopped.robot_state == RobotState.EMERGENCY_STOP
    assert flags(stopped) == only(emergency_stopped=True)
    assert stopped.joint_velocity == (0.0,) * 6
    assert stopped.joint_position == moving.joint_position  # stopped where it was
    assert r.produce_frame(5.0).joint_position == moving.joint_position
    with pytest.raises(RobotCommandError, match="reset first"):
        r.set_program_running(True, 5.0)
    r.reset(5.0)
    safe_off = r.produce_frame(5.1)
    assert safe_off.robot_state == RobotState.SAFE_OFF
    assert flags(safe_off) == only()
    standby = r.produce_frame(5.4)
    assert standby.robot_state == RobotState.STANDALONE_STANDBY
    assert flags(standby) == only(servo_on=True)
    assert r.produce_frame(7.0).robot_state == RobotState.STANDALONE_STANDBY  # no restart
    r.set_program_running(True, 7.0)
    resumed = r.produce_frame(7.002)
    assert resumed.robot_state == RobotState.STANDALONE_RUNNING
    assert (
        max(abs(a - b) for a, b in zip(resumed.joint_position, moving.joint_position, strict=True))
        < 0.01
    ), "the program resumes from where the arm stopped, without a jump"


def test_protective_stop_interrupts_with_safety_stopped() -> None:
    r = robot()
    r.produce_frame(2.0)
    r.protective_stop(2.0)
    frame = r.produce_frame(2.1)
    assert frame.robot_state == RobotState.INTERRUPTED
    assert flags(frame) == only(servo_on=True, safety_stopped=True)
    assert frame.joint_velocity == (0.0,) * 6
    r.reset(2.5)
    assert r.produce_frame(2.6).robot_state == RobotState.SAFE_OFF
    assert r.produce_frame(2.9).robot_state == RobotState.STANDALONE_STANDBY


def test_teach_button_gives_hand_guiding_with_its_flag() -> None:
    r = robot()
    r.produce_frame(2.0)
    r.set_teach_button(True, 2.0)
    frame = r.produce_frame(2.1)
    assert frame.robot_state == RobotState.MANUAL_HANDGUIDING
    assert flags(frame) == only(servo_on=True, direct_teach_button_pressed=True)
    assert frame.joint_velocity == (0.0,) * 6
    with pytest.raises(RobotCommandError, match="teach button"):
        r.set_program_running(True, 2.2)
    r.set_teach_button(False, 2.3)
    released = r.produce_frame(2.4)
    assert released.robot_state == RobotState.STANDALONE_STANDBY
    assert flags(released) == only(servo_on=True)


def test_power_button_flag_follows_the_button() -> None:
    r = robot()
    r.set_power_button(True, 2.0)
    frame = r.produce_frame(2.0)
    assert frame.power_button_pressed
    assert frame.robot_state == RobotState.STANDALONE_RUNNING
    r.set_power_button(False, 2.1)
    assert not r.produce_frame(2.1).power_button_pressed


def test_collaborative_mode_gives_the_collaborative_states() -> None:
    r = robot(collaborative=True)
    assert r.produce_frame(1.2).robot_state == RobotState.COLLABORATIVE_STANDBY
    assert r.produce_frame(1.7).robot_state == RobotState.COLLABORATIVE_RUNNING
    r.set_collaborative(False, 1.8)
    assert r.produce_frame(1.8).robot_state == RobotState.STANDALONE_RUNNING
    r.set_program_running(False, 1.9)
    r.set_collaborative(True, 1.9)
    assert r.produce_frame(1.9).robot_state == RobotState.COLLABORATIVE_STANDBY


@pytest.mark.parametrize("info", ROBOT_STATES, ids=lambda s: s.name)
def test_every_state_can_be_forced(info: object) -> None:
    value = info.value  # type: ignore[attr-defined]
    r = robot()
    r.produce_frame(2.0)
    r.force_state(value, 2.0)
    frame = r.produce_frame(2.5)
    assert frame.robot_state == value
    assert frame.emergency_stopped == (value == RobotState.EMERGENCY_STOP)
    assert frame.safety_stopped == (value == RobotState.INTERRUPTED)
    assert frame.servo_on == (
        value
        not in {
            RobotState.EMERGENCY_STOP,
            RobotState.INITIALIZING,
            RobotState.SAFE_OFF,
            RobotState.BACKDRIVE_HOLD,
            RobotState.BACKDRIVE_RELEASE,
            RobotState.BACKDRIVE_RELEASE_BY_COCKPIT,
        }
    )
    assert r.produce_frame(10.0).robot_state == value  # stays until the next command
    r.reset(10.0)
    assert r.produce_frame(10.5).robot_state == RobotState.STANDALONE_STANDBY


def test_forcing_an_unknown_value_is_reported_as_it_is() -> None:
    r = robot()
    r.force_state(99, 0.0)
    assert r.produce_frame(0.1).robot_state == 99
    with pytest.raises(RobotCommandError):
        r.force_state(256, 0.2)
    assert r.produce_frame(0.3).robot_state == 99


def test_refused_commands_change_nothing() -> None:
    r = robot()
    with pytest.raises(RobotCommandError, match="nothing to reset"):
        r.reset(1.2)
    assert r.produce_frame(1.2).robot_state == RobotState.STANDALONE_STANDBY
    r.estop(1.3)
    with pytest.raises(RobotCommandError):
        r.protective_stop(1.4)
    assert r.produce_frame(1.4).robot_state == RobotState.EMERGENCY_STOP
    with pytest.raises(RobotCommandError, match="limits"):
        r.hold_joints((0, 0, 170, 0, 0, 0), 1.5)  # J3 limit ±160°
    with pytest.raises(RobotCommandError, match="expected 6"):
        r.hold_joints((0, 0, 0), 1.5)
    assert r.produce_frame(1.6).joint_position == (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)


# ---------------------------------------------------------------------------------------- I/O


def test_outputs_follow_the_command_and_idle_holds_by_default() -> None:
    r = robot()
    command = zero_command()._replace(
        controlbox_do=(True, False) * 8,
        tool_do=(False, True, False, False, False, True),
        analog_output_type=(1, 0),
        analog_output=(7.5, 12.0),
    )
    r.consume_command(command, 0.1)
    frame = r.produce_frame(0.1)
    assert frame.controlbox_do == command.controlbox_do
    assert frame.tool_do == command.tool_do
    assert frame.analog_output_type == (1, 0)
    assert frame.analog_output == (7.5, 12.0)
    assert r.command_image() == command
    r.outputs_idle(0.2)
    assert r.produce_frame(0.2).controlbox_do == command.controlbox_do


def test_idle_behaviour_clear_clears_the_outputs() -> None:
    r = robot(idle_behaviour=IdleBehaviour.CLEAR)
    command = zero_command()._replace(controlbox_do=(True,) * 16, analog_output=(5.0, 5.0))
    r.consume_command(command, 0.1)
    r.outputs_idle(0.2)
    frame = r.produce_frame(0.2)
    assert frame.controlbox_do == (False,) * 16
    assert frame.analog_output == (0.0, 0.0)
    assert r.command_image() == command  # what the PLC last commanded is kept


def test_bit_output_registers_copy_the_input_registers() -> None:
    r = robot()
    registers = tuple(n in (0, 5, 40, 63) for n in range(64))
    r.consume_command(zero_command()._replace(bit_input_registers=registers), 0.1)
    assert r.produce_frame(0.1).bit_output_registers == registers


def test_register_mapping_is_a_setting() -> None:
    mapping = tuple((n + 1) % 64 for n in range(64))  # output n ← input n + 1
    r = robot(register_map=mapping)
    registers = tuple(n == 10 for n in range(64))
    r.consume_command(zero_command()._replace(bit_input_registers=registers), 0.1)
    out = r.produce_frame(0.1).bit_output_registers
    assert [n for n, bit in enumerate(out) if bit] == [9]


def test_register_map_from_text() -> None:
    mapping = parse_register_map("0=1, 1=0,63=-")
    assert mapping[:3] == (1, 0, 2)
    assert mapping[63] is None
    assert parse_register_map("") == tuple(range(64))
    for bad in ("0", "x=1", "64=0", "0=64", "0=a"):
        with pytest.raises(ValueError, match="register map"):
            parse_register_map(bad)


def test_di_1_follows_the_program_as_part_present() -> None:
    r = robot()
    seen = {r.produce_frame(t * 0.01).controlbox_di[0] for t in range(3000)}
    assert seen == {False, True}


def test_inputs_are_settable_and_ai_has_a_little_noise() -> None:
    r = robot()
    r.set_inputs(
        {
            "controlbox_di": {"3": True, "15": True},
            "tool_di": {"5": True},
            "analog_input": {"0": 12.0, "1": 3.3},
            "analog_input_type": {"1": 1},
        },
        0.1,
    )
    frame = r.produce_frame(0.1)
    assert frame.controlbox_di[3] and frame.controlbox_di[15]
    assert frame.tool_di == (False,) * 5 + (True,)
    assert frame.analog_input_type == (0, 1)
    assert frame.analog_input == pytest.approx((12.0, 3.3), abs=0.05)
    samples = {r.produce_frame(0.2 + i * 0.01).analog_input[0] for i in range(20)}
    assert len(samples) > 1, "AI carries noise"


@pytest.mark.parametrize(
    ("changes", "reason"),
    [
        ({"controlbox_di": {"0": True}}, "follows the program"),
        ({"controlbox_di": {"16": True}}, "out of range"),
        ({"controlbox_di": {"x": True}}, "out of range"),
        ({"controlbox_di": {"1": 1}}, "true or false"),
        ({"analog_input": {"0": "5"}}, "number"),
        ({"analog_input": {"0": float("nan")}}, "finite"),
        ({"analog_input_type": {"0": 2}}, "0 to 1"),
        ({"controlbox_do": {"0": True}}, "cannot be set"),
        ({"tool_di": [True] * 6}, "map"),
    ],
)
def test_bad_inputs_are_refused_and_nothing_changes(
    changes: dict[str, object], reason: str
) -> None:
    r = robot()
    before = r.produce_frame(0.1)
    # A valid change bundled with the bad one must not be applied either.
    bundle = {"tool_di": {"0": True}, **changes} if "tool_di" not in changes else changes
    with pytest.raises(RobotCommandError, match=reason):
        r.set_inputs(bundle, 0.2)  # type: ignore[arg-type]
    after = r.produce_frame(0.2)
    assert after.tool_di == before.tool_di
    assert after.controlbox_di[1:] == before.controlbox_di[1:]
    assert after.analog_input_type == before.analog_input_type
