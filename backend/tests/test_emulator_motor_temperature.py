"""``cobot-hmi emulator --motor-temperature-rise-c`` and the wear scenario file's
``motor_temperature_rise_c`` (docs/emulator.md, "The simulated robot" and "Wear"): 0 holds every
motor at room temperature while the program runs, so the health engine, which compares friction
only within one temperature band, reads a wear at once; without it the motors warm as before;
the command line's value wins over the file's; a value out of range is refused by name."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from cobot_hmi.cli import build_parser
from cobot_hmi.cli.emulator_verb import _robot
from cobot_hmi.emulator.robot import SimulatedRobot
from cobot_hmi.emulator.robot.wear import WearError, parse_scenario

TEN_MINUTES_S = 600.0


def _temperatures_after_running(*options: str) -> tuple[float, ...]:
    """The motors' temperatures after ten minutes of the demo program, in simulated time from
    now (the emulator's clock is the epoch's: a scenario's wear starts at ``time.time()``)."""
    args = build_parser().parse_args(["emulator", "--kinematic-refresh-ms", "0", *options])
    robot = _robot(args)
    assert isinstance(robot, SimulatedRobot)
    start_s = time.time()
    frame = robot.produce_frame(start_s)
    for step in range(1, int(TEN_MINUTES_S * 10) + 1):
        frame = robot.produce_frame(start_s + step / 10)
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


def _scenario(tmp_path: Path, body: dict[str, object]) -> str:
    path = tmp_path / "wear.json"
    path.write_text(json.dumps(body), encoding="utf-8")
    return str(path)


def test_the_scenario_file_holds_the_motors_with_its_wear(tmp_path: Path) -> None:
    wear = {"motor_temperature_rise_c": 0, "wear": [{"joint": 3, "friction_percent": 25}]}
    held = _temperatures_after_running("--wear", _scenario(tmp_path, wear))
    assert held == pytest.approx((25.0,) * 6, abs=0.01)


def test_the_command_line_wins_over_the_scenario_file(tmp_path: Path) -> None:
    path = _scenario(tmp_path, {"motor_temperature_rise_c": 0})
    warmed = _temperatures_after_running("--wear", path, "--motor-temperature-rise-c", "40")
    assert max(warmed) > 26.0, warmed


@pytest.mark.parametrize("value", [-1, 201, "warm", True])
def test_a_scenario_rise_out_of_range_is_refused_by_name(value: object) -> None:
    with pytest.raises(WearError) as error:
        parse_scenario({"motor_temperature_rise_c": value}, 6)
    assert error.value.field == "motor_temperature_rise_c"
