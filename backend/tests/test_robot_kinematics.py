"""Forward kinematics of the simulated arm against the controller's published check and against an
independent composition of the URDF transforms written here with plain 4×4 matrices."""

from __future__ import annotations

import math
from collections.abc import Sequence

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cobot_hmi.emulator.robot.kinematics import (
    IDENTITY,
    Transform,
    euler_zyz_deg,
    forward,
    from_euler_zyz_deg,
    position_mm,
    rotation_angle_deg,
    tcp_velocity,
)
from cobot_hmi.emulator.robot.models import M0609, M1013, RobotModel

Matrix = list[list[float]]

# The URDF joint origins, typed again from the sources (spec for the M1013, doosan-robot2's
# dsr_description2/urdf/m0609.urdf for the M0609) so the check does not reuse the model's table.
_H = math.pi / 2
URDF_ORIGINS = {
    "M1013": [
        ((0, 0, 0.1525), (0, 0, 0)),
        ((0, 0.0345, 0), (0, -_H, -_H)),
        ((0.620, 0, 0), (0, 0, _H)),
        ((0, -0.559, 0), (_H, 0, 0)),
        ((0, 0, 0), (-_H, 0, 0)),
        ((0, -0.121, 0), (_H, 0, 0)),
    ],
    "M0609": [
        ((0, 0, 0.1345), (0, 0, 0)),
        ((0, 0.0062, 0), (0, -_H, -_H)),
        ((0.411, 0, 0), (0, 0, _H)),
        ((0, -0.368, 0), (_H, 0, 0)),
        ((0, 0, 0), (-_H, 0, 0)),
        ((0, -0.121, 0), (_H, 0, 0)),
    ],
}


def matmul(a: Matrix, b: Matrix) -> Matrix:
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def rx(angle: float) -> Matrix:
    c, s = math.cos(angle), math.sin(angle)
    return [[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]]


def ry(angle: float) -> Matrix:
    c, s = math.cos(angle), math.sin(angle)
    return [[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]]


def rz(angle: float) -> Matrix:
    c, s = math.cos(angle), math.sin(angle)
    return [[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


def translation(x: float, y: float, z: float) -> Matrix:
    return [[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


def reference_fk(name: str, joints_deg: Sequence[float]) -> Matrix:
    """base → flange: for each joint, translate, Rz(yaw)·Ry(pitch)·Rx(roll), then Rz(q)."""
    m = translation(0, 0, 0)
    for (xyz, (roll, pitch, yaw)), q in zip(URDF_ORIGINS[name], joints_deg, strict=True):
        m = matmul(m, translation(*xyz))
        m = matmul(m, matmul(rz(yaw), matmul(ry(pitch), rx(roll))))
        m = matmul(m, rz(math.radians(q)))
    return m


def as_matrix(t: Transform) -> Matrix:
    return [list(t[0:4]), list(t[4:8]), list(t[8:12]), [0.0, 0.0, 0.0, 1.0]]


def test_published_m1013_check() -> None:
    """Spec: joints (30, 0, 90, 0, 90, 0)° → TCP (466.9, 309.4, 651.5) mm, (75, 180, 45)°."""
    kin = forward(M1013, (30, 0, 90, 0, 90, 0))
    x, y, z = position_mm(kin.tcp)
    assert (x, y, z) == pytest.approx((466.9, 309.4, 651.5), abs=0.5)
    a, b, c = euler_zyz_deg(kin.tcp)
    assert b == pytest.approx(180.0, abs=0.5)
    # B = 180 is Z-Y-Z's gimbal lock: only A − C is defined (R = Rz(A − C)·Ry(180°)), so the
    # published triple and ours must describe the same rotation, within 0.5°.
    published = from_euler_zyz_deg((x, y, z), (75.0, 180.0, 45.0))
    assert rotation_angle_deg(published, kin.tcp) <= 0.5
    assert a - c == pytest.approx(75.0 - 45.0, abs=0.5)


POSES = [
    (0, 0, 0, 0, 0, 0),
    (0, 0, 90, 0, 90, 0),
    (30, 0, 90, 0, 90, 0),
    (-45, 30, 60, 20, -70, 110),
    (170, -80, 140, -300, 45, 359),
    (12.5, 45.25, -120, 90, 91, -180),
]


@pytest.mark.parametrize("model", [M1013, M0609], ids=lambda m: m.name)
@pytest.mark.parametrize("joints", POSES)
def test_matches_independent_urdf_composition(model: RobotModel, joints: tuple[float, ...]) -> None:
    ours = as_matrix(forward(model, joints).tcp)
    reference = reference_fk(model.name, joints)
    for i in range(3):
        assert ours[i][3] == pytest.approx(reference[i][3], abs=1e-9)
        assert ours[i][:3] == pytest.approx(reference[i][:3], abs=1e-9)


def test_m0609_reach_differs_from_m1013() -> None:
    """J2 up, J3 at 0: the arm stretches up to the sum of its link lengths along z."""
    assert position_mm(forward(M1013, (0, 0, 0, 0, 0, 0)).tcp)[2] == pytest.approx(
        152.5 + 620 + 559 + 121
    )
    assert position_mm(forward(M0609, (0, 0, 0, 0, 0, 0)).tcp)[2] == pytest.approx(
        134.5 + 411 + 368 + 121
    )


angles = st.floats(min_value=-180, max_value=180, allow_nan=False)


@given(a=angles, b=st.floats(min_value=0, max_value=180), c=angles)
def test_euler_zyz_round_trip_gives_the_same_rotation(a: float, b: float, c: float) -> None:
    t = from_euler_zyz_deg((0, 0, 0), (a, b, c))
    back = from_euler_zyz_deg((0, 0, 0), euler_zyz_deg(t))
    assert rotation_angle_deg(t, back) < 1e-5


def test_euler_zyz_away_from_gimbal_lock_gives_the_same_angles() -> None:
    t = from_euler_zyz_deg((0, 0, 0), (75.0, 100.0, -45.0))
    assert euler_zyz_deg(t) == pytest.approx((75.0, 100.0, -45.0))


def test_euler_zyz_is_rz_ry_rz() -> None:
    ours = as_matrix(from_euler_zyz_deg((1, 2, 3), (10, 20, 30)))
    reference = matmul(
        translation(0.001, 0.002, 0.003),
        matmul(rz(math.radians(10)), matmul(ry(math.radians(20)), rz(math.radians(30)))),
    )
    for i in range(3):
        assert ours[i] == pytest.approx(reference[i])


def test_tool_offset_moves_the_tcp_in_the_flange_frame() -> None:
    joints = (-45, 30, 60, 20, -70, 110)
    flange = forward(M1013, joints).tcp
    tool = from_euler_zyz_deg((10, -20, 150), (90, 0, 0))
    tcp = forward(M1013, joints, tool).tcp
    expected = matmul(as_matrix(flange), as_matrix(tool))
    assert position_mm(tcp) == pytest.approx([expected[i][3] * 1000 for i in range(3)])
    # The tool's z offset is 150 mm away from the flange along the flange's z axis.
    offset = [(tcp[3 + 4 * i] - flange[3 + 4 * i]) * 1000 for i in range(3)]
    assert math.dist(offset, (0, 0, 0)) == pytest.approx(math.hypot(10, 20, 150))
    assert rotation_angle_deg(flange, tcp) == pytest.approx(90.0)


def _angular_velocity(before: Transform, after: Transform, dt_s: float) -> list[float]:
    """Axis × angle of R_after·R_beforeᵀ over dt (degree/s), from the plain matrices."""
    ra, rb = as_matrix(after), as_matrix(before)
    rel = [[sum(ra[i][k] * rb[j][k] for k in range(3)) for j in range(3)] for i in range(3)]
    angle = math.acos(max(-1.0, min(1.0, (rel[0][0] + rel[1][1] + rel[2][2] - 1) / 2)))
    scale = 0.0 if angle < 1e-12 else angle / (2 * math.sin(angle)) / dt_s
    return [
        math.degrees((rel[2][1] - rel[1][2]) * scale),
        math.degrees((rel[0][2] - rel[2][0]) * scale),
        math.degrees((rel[1][0] - rel[0][1]) * scale),
    ]


@pytest.mark.parametrize("model", [M1013, M0609], ids=lambda m: m.name)
def test_tcp_velocity_is_the_rate_of_change_of_the_pose(model: RobotModel) -> None:
    joints = (10, 25, 80, -15, 60, 30)
    rates = (20, -35, 50, 90, -120, 200)
    tool = from_euler_zyz_deg((0, 50, 120), (0, 30, 0))
    h = 1e-5

    def pose(t: float) -> Transform:
        return forward(model, [q + v * t for q, v in zip(joints, rates, strict=True)], tool).tcp

    before, after = pose(-h / 2), pose(h / 2)
    numeric_linear = [(after[3 + 4 * i] - before[3 + 4 * i]) * 1000 / h for i in range(3)]
    numeric_angular = _angular_velocity(before, after, h)
    linear, angular = tcp_velocity(forward(model, joints, tool), rates)
    assert linear == pytest.approx(numeric_linear, rel=1e-4, abs=1e-3)
    assert angular == pytest.approx(numeric_angular, rel=1e-4, abs=1e-3)


def test_identity_tool_is_the_flange() -> None:
    joints = (5, 10, 15, 20, 25, 30)
    assert forward(M1013, joints, IDENTITY).tcp == forward(M1013, joints).joint_frames[-1]
