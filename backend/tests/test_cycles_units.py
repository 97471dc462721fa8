"""Cycle timing's pure parts (issue 23): the trigger's text against the layout, the meter on
frames (edges, states, a silence), the trigger as a setting (TOML per robot, the one-robot
shortcut's flag and variable), and the emulator's cycle-start marker."""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.codec import Frame
from cobot_hmi.emulator.robot import RobotSettings as SimulationSettings
from cobot_hmi.emulator.robot import SimulatedRobot
from cobot_hmi.generated.frames import RobotState
from cobot_hmi.service.config.arguments import add_arguments, settings_from_args
from cobot_hmi.service.config.loading import load_settings
from cobot_hmi.service.cycles.meter import CycleMeter
from cobot_hmi.service.robots.cycle_trigger import TriggerError, parse_trigger
from cobot_hmi.service.service_settings import SettingsError
from emulator_harness import FAST_TIMINGS

RPI_S = 0.01


def frame_with(robot: SimulatedRobot, **changes: Any) -> Frame:
    return robot.produce_frame(0.0)._replace(**changes)


BASE = SimulatedRobot(SimulationSettings(timings=FAST_TIMINGS), start_s=0.0)


def registers(on: bool, index: int = 63) -> tuple[bool, ...]:
    return tuple(on and n == index for n in range(64))


def test_trigger_texts_and_their_refusals() -> None:
    marker = parse_trigger(" bit_output_registers.63:rising ")
    assert marker is not None
    assert (marker.field, marker.index, marker.falling) == ("bit_output_registers", 63, False)
    assert marker.label == "rising edge of Register out 63"  # as the checkout names it
    di5 = parse_trigger("controlbox_di.4:falling")
    assert di5 is not None and di5.falling and di5.index == 4
    assert di5.label == "falling edge of DI 5"
    servo = parse_trigger("servo_on:rising")
    assert servo is not None and servo.index is None
    assert servo.label == "rising edge of Servo on"
    running = parse_trigger("state:standalone_running")
    assert running is not None and running.state == RobotState.STANDALONE_RUNNING
    assert running.text == "state:STANDALONE_RUNNING"
    assert running.label == "entering Standalone running"
    assert parse_trigger("") is None
    for text, words in (
        ("bit_output_registers.64:rising", "bits 0–63"),
        ("joint_position.0:rising", "not a bit array"),
        ("tool_do.1:up", "rising or falling"),
        ("controlbox_di:rising", "needs its index"),
        ("state:DANCING", "no robot state"),
        ("bit_output_registers.3", "expected FIELD.INDEX"),
    ):
        with pytest.raises(TriggerError, match=words):
            parse_trigger(text)


def test_the_meter_measures_from_edge_to_edge_and_marks_a_cycle_across_a_silence() -> None:
    trigger = parse_trigger("bit_output_registers.63:rising")
    assert trigger is not None
    meter = CycleMeter("robot", trigger, max_gap_s=1.0)
    high, low = (
        frame_with(BASE, bit_output_registers=registers(True)),
        frame_with(BASE, bit_output_registers=registers(False)),
    )
    # The level at the first frame is no edge; the first edge only opens a cycle.
    assert meter.observe(high, 100.0) is None
    assert meter.observe(low, 100.01) is None
    assert meter.observe(high, 100.02) is None
    assert meter.started_at == 100.02
    assert meter.observe(high, 100.03) is None  # still high: no edge
    assert meter.observe(low, 100.5) is None
    cycle = meter.observe(high, 101.42)
    assert cycle is not None and (cycle.start, cycle.end) == (100.02, 101.42)
    assert cycle.duration_s == pytest.approx(1.4) and not cycle.interrupted
    # Frames stopped for longer than max_gap_s (a lost link): the cycle in progress goes on,
    # interrupted; the frame after the silence only says where the level is.
    assert meter.observe(high, 103.5) is None
    assert meter.started_at == 101.42
    assert meter.observe(low, 103.52) is None
    cycle = meter.observe(high, 104.01)
    assert cycle is not None and (cycle.start, cycle.end) == (101.42, 104.01)
    assert cycle.interruption == "no frames for 2.1 s (link lost)"
    assert meter.observe(low, 104.5) is None
    cycle = meter.observe(high, 105.01)
    assert cycle is not None and cycle.start == 104.01 and not cycle.interrupted


def test_falling_edges_and_states_start_cycles() -> None:
    falling = parse_trigger("controlbox_di.4:falling")
    state = parse_trigger("state:STANDALONE_RUNNING")
    assert falling is not None and state is not None
    di5_on = tuple(n == 4 for n in range(16))
    on = frame_with(BASE, controlbox_di=di5_on, robot_state=RobotState.STANDALONE_RUNNING)
    off = frame_with(BASE, controlbox_di=(False,) * 16, robot_state=RobotState.STANDALONE_STANDBY)
    for trigger, first_start in ((falling, 1.0), (state, 0.5)):
        meter = CycleMeter("robot", trigger)
        ends = [
            meter.observe(f, t)
            for f, t in (
                (off, 0.0),
                (on, 0.5),
                (off, 1.0),
                (on, 1.5),
                (off, 2.0),
                (on, 2.5),
                (off, 3.0),
            )
        ]
        cycles = [c for c in ends if c is not None]
        assert cycles[0].start == first_start
        assert all(c.duration_s == pytest.approx(1.0) for c in cycles)


def test_the_trigger_is_a_setting_per_robot_and_of_the_shortcut(tmp_path: Path) -> None:
    config = tmp_path / "hmi.toml"
    config.write_text(
        'cycle_trigger = "state:STANDALONE_RUNNING"\n'
        '[[robots]]\nname = "a"\nhost = "127.0.0.2"\ncycle_trigger = "tool_di.0:rising"\n'
        '[[robots]]\nname = "b"\nhost = "127.0.0.5"\n'
    )
    cell = load_settings({}, environ={}, config_file=config)
    assert [r.cycle_trigger for r in cell.cell.robots] == [
        "tool_di.0:rising",
        "state:STANDALONE_RUNNING",
    ]
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args(["--robot", "127.0.0.2", "--cycle-trigger", "controlbox_do.2:rising"])
    assert (
        settings_from_args(args, environ={}).cell.robots[0].cycle_trigger
        == "controlbox_do.2:rising"
    )
    environ = {"COBOT_HMI_ROBOT_HOST": "127.0.0.2", "COBOT_HMI_CYCLE_TRIGGER": "servo_on:falling"}
    assert load_settings({}, environ=environ).cell.robots[0].cycle_trigger == "servo_on:falling"
    with pytest.raises(SettingsError, match="bits 0–63"):
        load_settings(
            {"robot_host": "127.0.0.2", "cycle_trigger": "bit_output_registers.99:rising"},
            environ={},
        )


def test_the_emulator_marks_each_cycle_start_on_its_register() -> None:
    marked = SimulatedRobot(
        SimulationSettings(timings=FAST_TIMINGS, cycle_marker_register=63), start_s=0.0
    )
    plain = SimulatedRobot(SimulationSettings(timings=FAST_TIMINGS), start_s=0.0)
    rises: list[float] = []
    high_s = 0.0
    previous = False
    for n in range(4000):  # 40 s of frames at 10 ms
        t = n * RPI_S
        bit = marked.produce_frame(t).bit_output_registers[63]
        assert not plain.produce_frame(t).bit_output_registers[63]
        if bit and not previous:
            rises.append(t)
        high_s += RPI_S if bit else 0.0
        previous = bit
    cycles = marked.status()["program_cycles_completed"]
    assert isinstance(cycles, int) and cycles >= 3
    assert len(rises) == cycles + 1  # the first cycle's start, then each next one's
    periods = [b - a for a, b in itertools.pairwise(rises[1:])]  # (the first: power-on)
    assert max(periods) - min(periods) <= 2 * RPI_S + 1e-9
    # On through a good part of each cycle (its first steps): a late frame never hides an edge.
    assert 0.2 < high_s / (4000 * RPI_S) < 0.8


def test_a_stop_or_leaving_the_running_states_interrupts_the_cycle() -> None:
    """Issue 38: a cycle in which the robot stopped (e-stop, protective stop, safe off) or left
    its running states is interrupted, with what did it; one that ran through is whole."""
    trigger = parse_trigger("bit_output_registers.63:rising")
    assert trigger is not None
    running = RobotState.STANDALONE_RUNNING
    high = frame_with(BASE, bit_output_registers=registers(True), robot_state=running)
    low = frame_with(BASE, bit_output_registers=registers(False), robot_state=running)
    stops = (
        (
            low._replace(emergency_stopped=True, robot_state=RobotState.EMERGENCY_STOP),
            "Emergency stop",
        ),
        (low._replace(robot_state=RobotState.INTERRUPTED), "Protective stop"),
        (low._replace(robot_state=RobotState.SAFE_OFF), "Safe off (servo off)"),
        (low._replace(safety_stopped=True), "Safety stop"),
        (
            low._replace(robot_state=RobotState.STANDALONE_STANDBY),
            "left running: Standalone standby",
        ),
        (low, None),
    )
    for stop, words in stops:
        meter = CycleMeter("robot", trigger)
        t = 0.0
        for frame in (low, high, low, stop, low):
            assert meter.observe(frame, t) is None
            t += 0.01
        cycle = meter.observe(high, t)
        assert cycle is not None and cycle.interruption == words
        assert cycle.interrupted is (words is not None)
        # The next cycle starts whole.
        assert meter.observe(low, t + 0.01) is None
        after = meter.observe(high, t + 0.02)
        assert after is not None and not after.interrupted

    # A state trigger leaves its state every cycle: only a stop interrupts there.
    state = parse_trigger("state:STANDALONE_RUNNING")
    assert state is not None
    standby = low._replace(robot_state=RobotState.STANDALONE_STANDBY)
    meter = CycleMeter("robot", state)
    ends = [meter.observe(f, i * 0.5) for i, f in enumerate((standby, low, standby, low))]
    cycle = ends[-1]
    assert cycle is not None and not cycle.interrupted
