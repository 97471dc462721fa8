"""The simulated arm's motion and monitoring values, at model level (no sockets)."""

from __future__ import annotations

import itertools
import math
import random
import statistics

import pytest

from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot, StateTimings
from cobot_hmi.emulator.robot.dynamics import joint_torques
from cobot_hmi.emulator.robot.kinematics import (
    euler_zyz_deg,
    forward,
    from_euler_zyz_deg,
    position_mm,
    tcp_velocity,
)
from cobot_hmi.emulator.robot.models import M0609, M1013, RobotModel
from cobot_hmi.emulator.robot.trajectory import DEMO_STEPS, ProgramRunner, plan_move
from cobot_hmi.generated.frames import Frame, RobotState

STEP_S = 0.001


def cycle_duration_s(model: RobotModel) -> float:
    """One full program cycle from home: its moves' durations and its dwells, added up."""
    runner = ProgramRunner(model)
    position = model.demo_waypoints_deg[0]
    total = 0.0
    for step in DEMO_STEPS:
        if step.waypoint is None:
            total += step.dwell_s
            continue
        target = model.demo_waypoints_deg[step.waypoint]
        total += plan_move(
            position, target, runner.max_speed_deg_s, runner.max_accel_deg_s2
        ).duration_s
        position = target
    return total


def running_robot(model: str = "M1013", **changes: object) -> SimulatedRobot:
    timings = StateTimings(initializing_s=0.0, program_start_delay_s=0.0, safe_off_s=0.2)
    settings = RobotSettings(model=model, timings=timings)
    for name, value in changes.items():
        setattr(settings, name, value)
    robot = SimulatedRobot(settings, start_s=0.0)
    robot.produce_frame(0.0)
    return robot


@pytest.mark.parametrize("model", [M1013, M0609], ids=lambda m: m.name)
def test_a_full_cycle_stays_inside_the_limits(model: RobotModel) -> None:
    runner = ProgramRunner(model)
    position = model.demo_waypoints_deg[0]
    closest = [math.inf] * len(model.demo_waypoints_deg)
    elapsed = 0.0
    longest_rest_s = rest_s = 0.0
    while runner.cycles_completed < 1:
        sample = runner.advance(position, STEP_S)
        elapsed += STEP_S
        position = sample.position
        for q, qd, qdd, spec in zip(
            sample.position, sample.velocity, sample.acceleration, model.joints, strict=True
        ):
            assert abs(q) <= spec.limit_deg
            assert abs(qd) <= spec.max_speed_deg_s + 1e-9
            assert abs(qdd) <= spec.max_accel_deg_s2 + 1e-9
        if any(sample.velocity):
            rest_s = 0.0
        else:
            rest_s += STEP_S
            longest_rest_s = max(longest_rest_s, rest_s)
        for i, waypoint in enumerate(model.demo_waypoints_deg):
            closest[i] = min(closest[i], math.dist(waypoint, sample.position))
    assert len(set(model.demo_waypoints_deg)) >= 4
    assert max(closest) < 0.1, "the program reaches every waypoint"
    assert longest_rest_s >= 1.0, "the program pauses before it repeats"
    assert elapsed == pytest.approx(cycle_duration_s(model), abs=2 * STEP_S)


def test_the_program_repeats() -> None:
    model = M1013
    duration = cycle_duration_s(model)
    robot = running_robot()
    first = [robot.produce_frame(t).joint_position for t in (1.0, 2.0, 3.0)]
    again = [robot.produce_frame(duration + t).joint_position for t in (1.0, 2.0, 3.0)]
    for a, b in zip(first, again, strict=True):
        assert a == pytest.approx(b, abs=1e-6)


def test_a_move_is_trapezoidal_and_synchronized() -> None:
    move = plan_move((0, 0, 90, 0, 90, 0), (90, -10, 45, 0, 90, 200), [100] * 6, [200] * 6)
    assert move.target_deg == pytest.approx((90, -10, 45, 0, 90, 200))
    mid = move.sample(move.duration_s / 2)
    assert max(abs(v) for v in mid.velocity) == pytest.approx(100)  # J6 (200°) is the limit
    assert mid.acceleration == pytest.approx((0,) * 6)  # cruising
    end = move.sample(move.duration_s)
    assert end.velocity == (0.0,) * 6
    # Every joint arrives at the same time: all fractions of the way are equal.
    quarter = move.sample(move.duration_s / 4)
    fractions = [
        (q - s) / d
        for q, s, d in zip(quarter.position, move.start_deg, move.delta_deg, strict=True)
        if d
    ]
    assert max(fractions) - min(fractions) < 1e-12


def test_velocity_is_the_derivative_of_position() -> None:
    """Frames 1 ms apart: central differences of the positions give the reported velocities."""
    robot = running_robot()
    h = 0.0005
    checked = 0
    for i in range(400):
        t = 0.05 + i * 0.037
        before = robot.produce_frame(t - h).joint_position
        now = robot.produce_frame(t)
        after = robot.produce_frame(t + h).joint_position
        numeric = [(b - a) / (2 * h) for a, b in zip(before, after, strict=True)]
        # Where the acceleration jumps the central difference is off by at most a·h/2.
        tolerance = [
            max(abs(a) for a in (1e-6,)) + 0.5 * spec.max_accel_deg_s2 * h for spec in M1013.joints
        ]
        for n, v, tol in zip(numeric, now.joint_velocity, tolerance, strict=True):
            assert v == pytest.approx(n, abs=tol)
        checked += any(now.joint_velocity)
    assert checked > 100, "most samples were taken while the arm moved"


def test_tcp_velocity_in_frames_agrees_with_tcp_position() -> None:
    robot = running_robot()
    h = 0.0005
    for t in (1.23, 2.71, 4.4, 6.05):
        before = robot.produce_frame(t - h).tcp_position
        now = robot.produce_frame(t)
        after = robot.produce_frame(t + h).tcp_position
        numeric = [(b - a) / (2 * h) for a, b in zip(before, after, strict=True)]
        assert now.tcp_velocity == pytest.approx(numeric, abs=0.5)


def test_torque_is_gravity_at_rest_and_grows_with_acceleration() -> None:
    robot = running_robot(autostart_program=False)
    rest = robot.produce_frame(0.5)
    assert rest.robot_state == RobotState.STANDALONE_STANDBY
    # Home: upper arm vertical, forearm horizontal: J2 and J3 carry the same gravity torque.
    assert rest.joint_torque[1] == pytest.approx(rest.joint_torque[2], rel=1e-3)
    assert abs(rest.joint_torque[1]) > 20
    assert rest.joint_torque[0] == pytest.approx(0.0, abs=1e-9)  # J1's axis is vertical
    # Current ∝ torque, with a little noise.
    for torque, current, spec in zip(
        rest.joint_torque, rest.joint_motor_current, M1013.joints, strict=True
    ):
        assert current == pytest.approx(torque / spec.torque_per_amp_nm, abs=0.1)
    # While accelerating, J1 (no gravity load) needs torque.
    robot.set_program_running(True, 0.5)
    frame = next(
        f
        for f in (robot.produce_frame(0.5 + i * 0.005) for i in range(1, 100))
        if f.joint_velocity[0] != 0.0
    )
    assert abs(frame.joint_torque[0]) > 1.0


@pytest.mark.parametrize("model", [M1013, M0609], ids=lambda m: m.name)
def test_torque_matches_a_body_by_body_sum(model: RobotModel) -> None:
    """The moment-sum form of the model against the plain sum over every body beyond a joint."""
    rng = random.Random(5)
    g = 9.80665
    for _ in range(50):
        joints = [rng.uniform(-150, 150) for _ in range(6)]
        velocity = [rng.uniform(-90, 90) for _ in range(6)]
        acceleration = [rng.uniform(-300, 300) for _ in range(6)]
        kin = forward(model, joints)
        ours = joint_torques(model, kin, velocity, acceleration, payload_kg=2.0)
        bodies = [
            (
                link.mass_kg,
                [
                    sum(f[4 * r + c] * link.com_m[c] for c in range(3)) + f[4 * r + 3]
                    for r in range(3)
                ],
            )
            for f, link in zip(kin.joint_frames, model.links, strict=True)
        ] + [(2.0, [kin.tcp[3], kin.tcp[7], kin.tcp[11]])]
        for i, (frame, spec) in enumerate(zip(kin.joint_frames, model.joints, strict=True)):
            z = (frame[2], frame[6], frame[10])
            p = (frame[3], frame[7], frame[11])
            gravity = inertia = 0.0
            for mass, centre in bodies[i:]:
                r = [centre[k] - p[k] for k in range(3)]
                # Torque of the weight (0, 0, −m·g) about the axis: z · (r × F).
                gravity += z[0] * (r[1] * -mass * g) - z[1] * (r[0] * -mass * g)
                along = sum(r[k] * z[k] for k in range(3))
                inertia += mass * (sum(v * v for v in r) - along * along)
            expected = (
                -gravity
                + (inertia + spec.reflected_inertia_kg_m2) * math.radians(acceleration[i])
                + spec.viscous_friction_nm_s_deg * velocity[i]
            )
            assert ours[i] == pytest.approx(expected, rel=1e-9, abs=1e-9)


def test_motor_temperature_rises_from_room_toward_a_load_level_and_cools_when_off() -> None:
    robot = running_robot(thermal_time_constant_s=60.0)
    start = robot.produce_frame(0.0).joint_motor_temperature
    assert start == pytest.approx((25.0,) * 6)
    temperatures = [robot.produce_frame(t * 1.0).joint_motor_temperature for t in range(1, 601)]
    hot = temperatures[-1]
    assert max(hot) > 35.0, "a few tens of °C under load"
    assert max(hot) < 80.0
    assert all(h >= 25.0 for h in hot)
    # J2 (the most loaded joint) warms up monotonically.
    j2 = [t[1] for t in temperatures]
    assert all(b >= a - 0.5 for a, b in itertools.pairwise(j2))
    robot.estop(600.0)
    cooled = robot.produce_frame(900.0).joint_motor_temperature
    assert cooled[1] < hot[1] - 5
    assert robot.produce_frame(900.0).joint_motor_current == (0.0,) * 6


def test_external_values_are_small_noise() -> None:
    robot = running_robot()
    frames = [robot.produce_frame(i * 0.01) for i in range(300)]
    for name, limit in (
        ("joint_external_torque", 1.0),
        ("external_force", 5.0),
        ("external_moment", 0.5),
    ):
        values = [v for f in frames for v in getattr(f, name)]
        assert max(abs(v) for v in values) < limit
        assert statistics.pstdev(values) > 0.0
        assert abs(statistics.fmean(values)) < limit / 5


def test_same_seed_same_frames() -> None:
    a, b = running_robot(seed=7), running_robot(seed=7)
    times = [i * 0.013 for i in range(200)]
    assert [a.produce_frame(t) for t in times] == [b.produce_frame(t) for t in times]
    c = running_robot(seed=8)
    assert [c.produce_frame(t) for t in times] != [a.produce_frame(t) for t in times]


def test_kinematic_values_refresh_every_100_ms_when_asked() -> None:
    robot = running_robot(kinematic_refresh_ms=100.0)
    frames = [(t, robot.produce_frame(t)) for t in (1.0 + i * 0.01 for i in range(50))]
    positions = [f.joint_position for _, f in frames]
    changes = sum(1 for a, b in itertools.pairwise(positions) if a != b)
    assert 3 <= changes <= 5  # 0.5 s of frames every 10 ms: a new value every 100 ms
    # I/O and state are events: they change at once.
    robot.consume_command(robot.command_image()._replace(controlbox_do=(True,) * 16), 1.505)
    assert robot.produce_frame(1.506).controlbox_do == (True,) * 16
    robot.estop(1.507)
    assert robot.produce_frame(1.508).robot_state == RobotState.EMERGENCY_STOP


def test_tool_offset_appears_in_the_frame_and_moves_the_tcp() -> None:
    robot = running_robot(autostart_program=False)
    plain = robot.produce_frame(0.1)
    robot.set_tool_offset((0, 0, 200), (0, 0, 90), 0.2)
    with_tool = robot.produce_frame(0.3)
    assert with_tool.tool_offset_position == (0.0, 0.0, 200.0)
    assert with_tool.tool_offset_orientation == (0.0, 0.0, 90.0)
    # Home: the flange points down, so a 200 mm tool lowers the TCP by 200 mm.
    assert with_tool.tcp_position[2] == pytest.approx(plain.tcp_position[2] - 200)
    assert with_tool.tcp_orientation[0] == pytest.approx(plain.tcp_orientation[0] - 90)


def test_each_monitoring_value_lands_in_its_own_frame_field() -> None:
    # produce_frame builds the Frame positionally (for speed): values of the same shape must not
    # trade places. Recompute each from the frame's own joint values and compare.
    robot = running_robot(tool_offset_position_mm=(0.0, 0.0, 100.0))
    frame = next(
        f for f in (robot.produce_frame(1.0 + i * 0.01) for i in range(300)) if f.joint_velocity[1]
    )
    kin = forward(M1013, frame.joint_position, from_euler_zyz_deg((0.0, 0.0, 100.0), (0, 0, 0)))
    assert frame.tcp_position == pytest.approx(position_mm(kin.tcp), abs=1e-9)
    assert frame.tcp_orientation == pytest.approx(euler_zyz_deg(kin.tcp), abs=1e-9)
    linear, angular = tcp_velocity(kin, frame.joint_velocity)
    assert frame.tcp_velocity == pytest.approx(linear, abs=1e-9)
    assert frame.tcp_angular_velocity == pytest.approx(angular, abs=1e-9)
    for torque, current, spec in zip(
        frame.joint_torque, frame.joint_motor_current, M1013.joints, strict=True
    ):
        assert current == pytest.approx(torque / spec.torque_per_amp_nm, abs=0.1)
    assert all(20.0 < t < 30.0 for t in frame.joint_motor_temperature)
    assert frame.tool_offset_position == (0.0, 0.0, 100.0)
    assert frame.tool_offset_orientation == (0.0, 0.0, 0.0)
    assert frame.robot_state == RobotState.STANDALONE_RUNNING and frame.servo_on


def test_m0609_is_selectable() -> None:
    robot = running_robot(model="m0609")
    frame: Frame = robot.produce_frame(0.0)
    home = M0609.demo_waypoints_deg[0]
    expected = forward(M0609, home).tcp
    assert frame.tcp_position == pytest.approx([expected[i] * 1000 for i in (3, 7, 11)])
    with pytest.raises(KeyError, match="M1013"):
        running_robot(model="h2017")


def test_hold_joints_stops_the_program_and_holds_there() -> None:
    robot = running_robot()
    robot.produce_frame(1.0)
    robot.hold_joints((10, 20, 30, 40, 50, 60), 1.1)
    for t in (1.1, 1.5, 3.0):
        frame = robot.produce_frame(t)
        assert frame.joint_position == (10.0, 20.0, 30.0, 40.0, 50.0, 60.0)
        assert frame.joint_velocity == (0.0,) * 6
        assert frame.robot_state == RobotState.STANDALONE_STANDBY
    # Resuming moves smoothly from there (no jump).
    robot.set_program_running(True, 3.0)
    frame = robot.produce_frame(3.001)
    assert (
        max(abs(a - b) for a, b in zip(frame.joint_position, (10, 20, 30, 40, 50, 60), strict=True))
        < 0.01
    )
    assert all(math.isfinite(v) for v in frame.joint_velocity)


def test_program_cycles_within_a_minute() -> None:
    assert cycle_duration_s(M1013) < 60
    assert len(DEMO_STEPS) >= 4
