"""The simulated robot's word on how long its frame holds by itself
(``SimulatedRobot.frame_still_until_s``): the class 1 engine leaves the pump's periodic T→O stream
alone until then, so the word must never be late (the frame does not change before it) and should
say more than "now" (else the engine wakes at every RPI for nothing)."""

from __future__ import annotations

from cobot_hmi.emulator.process_image import HoldsStill
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.generated.frames import Frame

START_S = 1000.0
STEP_S = 0.002


def _walk(robot: SimulatedRobot, from_s: float, to_s: float) -> list[tuple[float, float, Frame]]:
    """Each instant's frame and the robot's word at it, every ``STEP_S``, with no command."""
    out = []
    steps = round((to_s - from_s) / STEP_S)
    for i in range(steps):
        now_s = from_s + i * STEP_S
        frame = robot.produce_frame(now_s)
        out.append((now_s, robot.frame_still_until_s(), frame))
    return out


def _check_never_late(walk: list[tuple[float, float, Frame]]) -> float:
    """Every frame up to each word equals the frame the word was given with; the share of
    instants whose word reached past the next step."""
    useful = 0
    for i, (now_s, until_s, frame) in enumerate(walk):
        assert until_s >= now_s
        if until_s >= now_s + STEP_S:
            useful += 1
        for later_s, _, later in walk[i + 1 :]:
            if later_s >= until_s:
                break
            assert later == frame, (
                f"changed at {later_s - START_S:.3f} s, said still until "
                f"{until_s - START_S:.3f} s (at {now_s - START_S:.3f} s)"
            )
    return useful / len(walk)


def _robot(refresh_ms: float) -> SimulatedRobot:
    settings = RobotSettings(seed=3, cycle_marker_register=63, kinematic_refresh_ms=refresh_ms)
    return SimulatedRobot(settings, start_s=START_S)


def test_the_frame_holds_until_the_robot_says_through_start_program_and_stops() -> None:
    robot = _robot(100.0)
    assert isinstance(robot, HoldsStill)
    # Power on: INITIALIZING 2 s, standby, the program from 3 s on (moves, dwells, the marker).
    useful = _check_never_late(_walk(robot, START_S, START_S + 14.0))
    assert useful > 0.8
    at_s = START_S + 14.0
    robot.protective_stop(at_s)
    _check_never_late(_walk(robot, at_s, at_s + 0.5))
    at_s += 0.5
    robot.reset(at_s)  # SAFE_OFF for 0.5 s, then standby
    _check_never_late(_walk(robot, at_s, at_s + 1.5))
    at_s += 1.5
    robot.set_program_running(True, at_s)
    assert _check_never_late(_walk(robot, at_s, at_s + 6.0)) > 0.8


def test_a_robot_fresh_at_every_instant_never_holds() -> None:
    robot = _robot(0.0)
    walk = _walk(robot, START_S, START_S + 4.0)
    assert all(until_s == now_s for now_s, until_s, _ in walk)


def test_after_a_command_the_word_waits_for_the_next_frame() -> None:
    robot = _robot(100.0)
    robot.produce_frame(START_S + 5.0)
    robot.estop(START_S + 5.01)
    assert robot.frame_still_until_s() == START_S + 5.01  # no frame of this instant yet
