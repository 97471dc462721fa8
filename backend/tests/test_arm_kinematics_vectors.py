"""The golden forward-kinematics vectors (frontend/src/generated/armKinematicsVectors.json, written
by ``cobot-hmi codegen`` from the emulator's model; Vitest checks the 3D view's TypeScript against
the same file): the Python model reproduces every one within the file's tolerance, and the
vectors hold the spread they claim (every arm, each joint alone both ways, within the limits,
singular poses that are singular)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest

from cobot_hmi.arms import ARMS, Arm
from cobot_hmi.codegen import ARM_VECTORS_FILE
from cobot_hmi.codegen.arm_vectors import (
    NEAR_SINGULAR_DEG,
    RANDOM_POSES_PER_ARM,
    TOLERANCE,
    arm_vectors_json,
)
from cobot_hmi.emulator.robot.kinematics import (
    DEG_PER_RAD,
    Transform,
    forward,
    from_euler_zyz_deg,
    position_mm,
    rotation_angle_deg,
    tcp_velocity,
)
from cobot_hmi.emulator.robot.models import RobotModel, model_by_name

GOLDEN: dict[str, Any] = json.loads(ARM_VECTORS_FILE.read_text(encoding="utf-8"))

POSITION_TOLERANCE_MM: float = GOLDEN["tolerance"]["position_mm"]
ORIENTATION_TOLERANCE_DEG: float = GOLDEN["tolerance"]["orientation_deg"]


def _rotation(rows: Sequence[Sequence[float]]) -> Transform:
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rows
    return (r00, r01, r02, 0.0, r10, r11, r12, 0.0, r20, r21, r22, 0.0)


def _smallest_singular_value(model: RobotModel, joints_deg: Sequence[float]) -> float:
    """Of the geometric Jacobian in m/rad and rad/rad: column i is the TCP's velocity when joint i
    alone turns."""
    kin = forward(model, joints_deg)
    columns = []
    for joint in range(len(joints_deg)):
        rate = [0.0] * len(joints_deg)
        rate[joint] = 1.0
        linear_mm_s, angular_deg_s = tcp_velocity(kin, rate)
        # mm/s per °/s is m per 1000 · (π/180) rad; °/s per °/s is rad per rad.
        columns.append([v * DEG_PER_RAD / 1000.0 for v in linear_mm_s] + list(angular_deg_s))
    jacobian = np.array(columns).T
    return float(np.linalg.svd(jacobian, compute_uv=False)[-1])


def _of_kind(arm: str, kind: str) -> list[dict[str, Any]]:
    return [v for v in GOLDEN["arms"][arm] if v["kind"] == kind]


def test_the_file_is_what_the_model_generates_now() -> None:
    assert ARM_VECTORS_FILE.read_text(encoding="utf-8") == arm_vectors_json(), (
        "run `cobot-hmi codegen`"
    )


def test_the_file_states_the_generators_tolerance() -> None:
    assert GOLDEN["tolerance"] == TOLERANCE
    assert 0 < POSITION_TOLERANCE_MM <= 1e-3
    assert 0 < ORIENTATION_TOLERANCE_DEG <= 1e-3


def test_every_arm_has_vectors_and_no_other() -> None:
    assert list(GOLDEN["arms"]) == [arm.name for arm in ARMS]
    for arm in ARMS:
        cases = [v["case"] for v in GOLDEN["arms"][arm.name]]
        assert len(cases) == len(set(cases)), f"{arm.name}: case names repeat"


def _deviations(arm: str, vector: dict[str, Any]) -> list[str]:
    """What of one vector the Python model misses by more than the tolerance, in words."""
    kin = forward(model_by_name(arm), vector["joints_deg"])
    found = []
    tcp_mm = math.dist(position_mm(kin.tcp), vector["tcp_position_mm"])
    if not tcp_mm <= POSITION_TOLERANCE_MM:
        found.append(f"TCP {tcp_mm:.3g} mm off")
    for joint, (frame, origin) in enumerate(
        zip(kin.joint_frames, vector["joint_origins_mm"], strict=True), start=1
    ):
        joint_mm = math.dist(position_mm(frame), origin)
        if not joint_mm <= POSITION_TOLERANCE_MM:
            found.append(f"J{joint} origin {joint_mm:.3g} mm off")
    golden_rotation = _rotation(vector["tcp_rotation"])
    turn_deg = rotation_angle_deg(kin.tcp, golden_rotation)
    if not turn_deg <= ORIENTATION_TOLERANCE_DEG:
        found.append(f"orientation {turn_deg:.3g}° off")
    # A, B, C describe the same rotation (compared as rotations: at B = 0 or 180 the three
    # numbers are one choice among many).
    from_abc = from_euler_zyz_deg((0.0, 0.0, 0.0), vector["tcp_abc_deg"])
    abc_deg = rotation_angle_deg(from_abc, golden_rotation)
    if not abc_deg <= ORIENTATION_TOLERANCE_DEG:
        found.append(f"A, B, C {abc_deg:.3g}° from the rotation")
    return found


@pytest.mark.parametrize("arm", ARMS, ids=lambda a: a.name)
def test_the_python_model_reproduces_every_vector(arm: Arm) -> None:
    """One test per arm (not per vector), naming every case it misses."""
    missed = {
        vector["case"]: found
        for vector in GOLDEN["arms"][arm.name]
        if (found := _deviations(arm.name, vector))
    }
    assert not missed


def test_a_vector_off_by_a_millimetre_is_missed() -> None:
    (home,) = [v for v in GOLDEN["arms"]["M1013"] if v["case"].startswith("home")]
    assert _deviations("M1013", home) == []
    x, y, z = home["tcp_position_mm"]
    moved = {**home, "tcp_position_mm": [x, y, z + 1.0]}
    assert _deviations("M1013", moved) == ["TCP 1 mm off"]


@pytest.mark.parametrize("arm", ARMS, ids=lambda a: a.name)
def test_every_pose_is_within_the_joint_limits(arm: Arm) -> None:
    for vector in GOLDEN["arms"][arm.name]:
        joints = vector["joints_deg"]
        assert len(joints) == len(arm.joints)
        for q, spec in zip(joints, arm.joints, strict=True):
            assert abs(q) <= spec.limit_deg, f"{vector['case']}: {q} outside ±{spec.limit_deg}"


@pytest.mark.parametrize("arm", ARMS, ids=lambda a: a.name)
def test_the_spread_covers_zero_each_joint_alone_both_ways_and_random_poses(arm: Arm) -> None:
    assert [v["joints_deg"] for v in _of_kind(arm.name, "zero")] == [[0.0] * 6]
    moved: dict[int, set[float]] = {}
    for vector in _of_kind(arm.name, "one joint"):
        nonzero = [(i, q) for i, q in enumerate(vector["joints_deg"]) if q != 0.0]
        assert len(nonzero) == 1, vector["case"]
        moved.setdefault(nonzero[0][0], set()).add(nonzero[0][1])
    for joint, spec in enumerate(arm.joints):
        values = moved.get(joint, set())
        assert {spec.limit_deg, -spec.limit_deg} <= values, f"J{joint + 1} at its limits"
        assert any(0 < q < 180 for q in values) and any(-180 < q < 0 for q in values)
    random_poses = [v["joints_deg"] for v in _of_kind(arm.name, "random")]
    assert len(random_poses) == RANDOM_POSES_PER_ARM
    # Drawn over the whole range: every joint takes both signs and no two poses are alike.
    assert len({tuple(p) for p in random_poses}) == len(random_poses)
    for joint in range(len(arm.joints)):
        assert {math.copysign(1.0, p[joint]) for p in random_poses} == {1.0, -1.0}


@pytest.mark.parametrize("arm", ARMS, ids=lambda a: a.name)
def test_singular_poses_are_singular_and_near_ones_nearly(arm: Arm) -> None:
    """The Jacobian loses rank on the singular poses (smallest singular value ~1e-16 against
    about 0.6 on a generic pose), and 0.001° away it is small but not zero."""
    model = model_by_name(arm.name)
    singular = _of_kind(arm.name, "singular") + _of_kind(arm.name, "zero")
    near = _of_kind(arm.name, "near singular")
    names = " ".join(v["case"] for v in singular)
    assert all(word in names for word in ("wrist", "elbow", "shoulder")), names
    assert len(near) == 2 * (len(singular) - 1)
    generic = min(
        _smallest_singular_value(model, v["joints_deg"]) for v in _of_kind(arm.name, "reference")
    )
    for vector in singular:
        assert _smallest_singular_value(model, vector["joints_deg"]) < 1e-9 * generic, vector[
            "case"
        ]
    step_rad = math.radians(NEAR_SINGULAR_DEG)
    for vector in near:
        sigma = _smallest_singular_value(model, vector["joints_deg"])
        assert 1e-2 * step_rad * generic < sigma < 1e2 * step_rad * generic, vector["case"]


def test_the_m1013_vector_at_the_published_check_is_the_controllers() -> None:
    """Spec (docs/emulator.md): joints (30, 0, 90, 0, 90, 0)° → TCP (466.9, 309.4, 651.5) mm."""
    (check,) = [v for v in GOLDEN["arms"]["M1013"] if v["joints_deg"] == [30, 0, 90, 0, 90, 0]]
    assert check["tcp_position_mm"] == pytest.approx([466.9, 309.4, 651.5], abs=0.05)
