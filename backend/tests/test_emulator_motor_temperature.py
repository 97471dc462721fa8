"""``cobot-hmi emulator --motor-temperature-rise-c`` (docs/emulator.md, "The simulated robot"):
0 holds every motor at room temperature while the program runs, so the health engine, which
compares friction only within one temperature band, reads a wear at once; without it the motors
warm as before; a value out of range is refused by the command line."""

from __future__ import annotations

import pytest

from cobot_hmi.cli import build_parser
from cobot_hmi.cli.emulator_verb import _robot
from cobot_hmi.emulator.robot import SimulatedRobot

TEN_MINUTES_S = 600.0


def _temperatures_after_running(*options: str) -> tuple[float, ...]:
    """The motors' temperatures after ten minutes of the demo program, in simulated time."""
    args = build_parser().parse_args(["emulator", "--kinematic-refresh-ms", "0", *options])
    robot = _robot(args)
    assert isinstance(robot, SimulatedRobot)
    frame = robot.produce_frame(0.0)
    for step in range(1, int(TEN_MINUTES_S * 10) + 1):
        frame = robot.produce_frame(step / 10)
    assert any(abs(current) > 0.5 for current in frame.joint_motor_current)  # it works
    return frame.joint_motor_temperature


def test_zero_rise_holds_the_motors_at_room_temperature() -> None:
    held = _temperatures_after_running("--motor-temperature-rise-c", "0")
    assert held == pytest.approx((25.0,) * 6, abs=0.01)


def test_without_the_option_the_motors_warm_with_their_current() -> None:
    warmed = _temperatures_after_running()
    assert max(warmed) > 26.0, warmed


@pytest.mark.parametrize("value", ["-1", "201", "warm"])
def test_a_rise_out_of_range_is_refused(value: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        build_parser().parse_args(["emulator", "--motor-temperature-rise-c", value])
    assert exit_.value.code == 2
    assert "--motor-temperature-rise-c" in capsys.readouterr().err
