"""The simulated robot's monitoring values refresh on a fixed grid, as the controller's do (every
100 ms on its own clock, docs/emulator.md): a read that comes late (the emulator's loop on a
loaded host wakes a few ms to tens of ms after the robot's next change) must give the values of
the grid instant, not of the late read, and must not move the later refreshes. They did: each
refresh happened at the read (``_monitoring_at_s = now``), so its values were of the late instant
and the grid drifted by every lateness; the health engine, which takes the samples' spacing as
whole frame periods of the robot's own clock (``health.samples``), then read wrong accelerations
(the spacing in motion time was the snapped one plus the lateness)."""

from __future__ import annotations

import itertools

import pytest

from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.generated.frames import Frame

REFRESH_S = 0.1
MONITORING_FIELDS = (
    "joint_position",
    "joint_velocity",
    "joint_motor_current",
    "joint_torque",
    "joint_external_torque",
    "tcp_position",
    "tcp_velocity",
    "analog_input",
)
LATENESS_S = (0.0, 0.013, 0.047, 0.002, 0.081, 0.029, 0.066, 0.0, 0.092, 0.038)
"""How late each grid instant's read comes (under one period: no refresh is skipped)."""


def _robot() -> SimulatedRobot:
    return SimulatedRobot(
        RobotSettings(seed=7, cycle_marker_register=63, kinematic_refresh_ms=REFRESH_S * 1000),
        start_s=0.0,
    )


def _monitoring(frame: Frame) -> list[float]:
    return [float(v) for name in MONITORING_FIELDS for v in getattr(frame, name)]


def test_late_reads_give_the_grid_instants_values() -> None:
    on_time, late = _robot(), _robot()
    moving = 0
    # From 3.5 s (the program moves the arm from 3 s on) for 6 s: moves and dwells.
    for k, lateness_s in zip(range(35, 95), itertools.cycle(LATENESS_S), strict=False):
        grid_s = k * REFRESH_S
        expected = on_time.produce_frame(grid_s)
        read_s = grid_s + lateness_s
        got = late.produce_frame(read_s)
        assert _monitoring(got) == pytest.approx(_monitoring(expected), abs=1e-9), (
            f"read {lateness_s * 1e3:.0f} ms after the grid instant {grid_s:.1f} s"
        )
        # The frame holds the grid instant's values until the next one, whatever reads between.
        between = late.produce_frame(read_s + (REFRESH_S - lateness_s) / 2)
        assert _monitoring(between) == _monitoring(got)
        assert late.frame_still_until_s() <= grid_s + REFRESH_S
        moving += any(expected.joint_velocity)
    assert moving > 20  # the arm moved through most of it: late values would have differed


def test_an_event_refresh_does_not_move_the_grid() -> None:
    robot = _robot()
    robot.produce_frame(5.0)
    robot.set_tool_offset((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), 5.03)  # fresh values at once
    after_event = robot.produce_frame(5.035)
    assert robot.frame_still_until_s() == pytest.approx(5.1, abs=1e-6)
    reference = _robot()
    reference.produce_frame(5.0)
    reference.set_tool_offset((0.0, 0.0, 100.0), (0.0, 0.0, 0.0), 5.03)
    reference.produce_frame(5.035)
    # The next refresh is the grid's (5.1 s), not the event's plus a period (5.13 s).
    assert _monitoring(robot.produce_frame(5.12)) == pytest.approx(
        _monitoring(reference.produce_frame(5.1)), abs=1e-9
    )
    assert _monitoring(after_event) != _monitoring(robot.produce_frame(5.12))
