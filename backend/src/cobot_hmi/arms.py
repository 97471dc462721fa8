"""Layer: layout level, pure data (no I/O). Imports nothing of the project.

The arms the product knows, as their makers publish them: each joint's URDF origin, position and
speed limit, and the mass and centre of mass of the link it moves. One place for these numbers:
the emulator's robot model (``emulator/robot/models.py``) builds on them, and ``cobot-hmi
codegen`` writes them into ``frontend/src/generated/arms.ts`` for the panel's 3D view
(``codegen/arms_ts.py``).

Sources:
- M1013 joint origins, position limits and speed limits: docs/emulator.md, "Reference
  facts the model follows" (Doosan's public ``dsr_description``). Where an older copy of Doosan's
  xacro (``doosan-robotics/doosan-robot``, ``dsr_description/xacro/macro.m1013.white.xacro``) puts
  J6 at y = −0.124 m, the documented −0.121 m is kept: it is the one that reproduces the
  controller's published forward-kinematics check (Z = 651.5 mm).
- M1013 link masses and centres of mass: ``doosan-robotics/doosan-robot``,
  ``dsr_description/xacro/macro.m1013.white.xacro`` (each centre of mass in its own link frame).
- M0609 joint origins, limits, masses and centres of mass: ``DoosanRobotics/doosan-robot2``,
  ``dsr_description2/urdf/m0609.urdf`` (J1 z 0.1345 m, J2 y 0.0062 m, J3 x 0.411 m, J4 y −0.368 m,
  J6 y −0.121 m; J3 ±150°; 150°/s on J1–J2, 180°/s on J3, 225°/s on J4–J6). The URDF writes
  π/2 as 1.571; exact π/2 is used here, as the spec does for the M1013.
- Rated joint torque, speed and life (``JointRating``, read by the health engine's reducer-life
  law, docs/health.md): Doosan does not publish them for these arms, so every one is an
  assumption (``assumed=True``), taken from the strain-wave reducer sizes an arm of this reach
  and payload carries (rated torque at the maker's rated input speed of 2000 rpm through a
  100:1 ratio, i.e. 120°/s at the joint, and the maker's rated life of 10,000 h). Replace a value
  with the maker's when it is published, and clear its ``assumed``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

Vector3 = tuple[float, float, float]

_HALF_PI: Final = math.pi / 2


@dataclass(frozen=True, slots=True)
class ArmJoint:
    """One revolute joint: its URDF origin in the parent link frame and its published limits.

    Every joint of these arms turns about the local z axis of its child link frame.
    """

    origin_xyz_m: Vector3
    origin_rpy_rad: Vector3
    limit_deg: float
    """Symmetric position limit: the joint stays within ±limit_deg."""
    max_speed_deg_s: float


@dataclass(frozen=True, slots=True)
class ArmLink:
    """The mass of the link a joint moves and its centre of mass in that link's frame."""

    mass_kg: float
    com_m: Vector3


@dataclass(frozen=True, slots=True)
class JointRating:
    """A joint reducer's rated values, the reference of the life law
    ``L = L_rated · (ω_rated/ω)·(τ_rated/τ)^(10/3)`` (docs/health.md)."""

    rated_torque_nm: float
    rated_speed_deg_s: float
    rated_life_h: float
    assumed: bool = True
    """True where the maker has not published the value (docs/health.md says so)."""


@dataclass(frozen=True, slots=True)
class Arm:
    """An arm's published geometry: six joints, J1 first, and the six links they move; and
    each joint's rated values (``ratings``, J1 first)."""

    name: str
    joints: tuple[ArmJoint, ...]
    links: tuple[ArmLink, ...]
    ratings: tuple[JointRating, ...] = ()


M1013_ARM: Final = Arm(
    name="M1013",
    joints=(
        ArmJoint((0.0, 0.0, 0.1525), (0.0, 0.0, 0.0), 360.0, 120.0),
        ArmJoint((0.0, 0.0345, 0.0), (0.0, -_HALF_PI, -_HALF_PI), 360.0, 120.0),
        ArmJoint((0.620, 0.0, 0.0), (0.0, 0.0, _HALF_PI), 160.0, 180.0),
        ArmJoint((0.0, -0.559, 0.0), (_HALF_PI, 0.0, 0.0), 360.0, 225.0),
        ArmJoint((0.0, 0.0, 0.0), (-_HALF_PI, 0.0, 0.0), 360.0, 225.0),
        ArmJoint((0.0, -0.121, 0.0), (_HALF_PI, 0.0, 0.0), 360.0, 225.0),
    ),
    links=(
        ArmLink(7.8, (0.000119, 0.0428, -0.006383)),
        ArmLink(10.83, (0.25973, -5.3e-05, 0.15782)),
        ArmLink(3.68, (-1.5e-05, -0.006702, 0.044608)),
        ArmLink(3.82, (7.1e-05, 0.091879, -0.18252)),
        ArmLink(2.82, (-0.000273, 0.003651, 0.032088)),
        ArmLink(1.16, (-0.000292, 7e-06, -0.0539)),
    ),
    # Assumed (not published by Doosan): a size-40 reducer in J1–J2, size 32 in J3, size 20 in
    # the wrist; 120°/s rated speed (2000 rpm in, 100:1), 10,000 h rated life.
    ratings=(
        JointRating(294.0, 120.0, 10_000.0, assumed=True),
        JointRating(294.0, 120.0, 10_000.0, assumed=True),
        JointRating(137.0, 120.0, 10_000.0, assumed=True),
        JointRating(40.0, 120.0, 10_000.0, assumed=True),
        JointRating(40.0, 120.0, 10_000.0, assumed=True),
        JointRating(40.0, 120.0, 10_000.0, assumed=True),
    ),
)

M0609_ARM: Final = Arm(
    name="M0609",
    joints=(
        ArmJoint((0.0, 0.0, 0.1345), (0.0, 0.0, 0.0), 360.0, 150.0),
        ArmJoint((0.0, 0.0062, 0.0), (0.0, -_HALF_PI, -_HALF_PI), 360.0, 150.0),
        ArmJoint((0.411, 0.0, 0.0), (0.0, 0.0, _HALF_PI), 150.0, 180.0),
        ArmJoint((0.0, -0.368, 0.0), (_HALF_PI, 0.0, 0.0), 360.0, 225.0),
        ArmJoint((0.0, 0.0, 0.0), (-_HALF_PI, 0.0, 0.0), 360.0, 225.0),
        ArmJoint((0.0, -0.121, 0.0), (_HALF_PI, 0.0, 0.0), 360.0, 225.0),
    ),
    links=(
        ArmLink(5.02, (7.2e-05, 0.036227, -0.003417)),
        ArmLink(8.04, (0.20447, 2.6e-05, 0.16005)),
        ArmLink(3.6, (-2.2e-05, -0.006867, 0.043445)),
        ArmLink(3.57, (4e-05, 0.097079, -0.10981)),
        ArmLink(2.83, (-6.8e-05, 0.003827, 0.031969)),
        ArmLink(1.16, (-3e-05, -4.5e-05, -0.0539)),
    ),
    # Assumed (not published by Doosan): a size-32 reducer in J1–J2, size 25 in J3, size 20 in
    # the wrist; 120°/s rated speed (2000 rpm in, 100:1), 10,000 h rated life.
    ratings=(
        JointRating(178.0, 120.0, 10_000.0, assumed=True),
        JointRating(178.0, 120.0, 10_000.0, assumed=True),
        JointRating(84.0, 120.0, 10_000.0, assumed=True),
        JointRating(40.0, 120.0, 10_000.0, assumed=True),
        JointRating(40.0, 120.0, 10_000.0, assumed=True),
        JointRating(40.0, 120.0, 10_000.0, assumed=True),
    ),
)

ARMS: Final = (M1013_ARM, M0609_ARM)
"""Every known arm; the first is the default."""


def arm_by_name(name: str) -> Arm:
    """The arm called ``name`` (case-insensitive); ``KeyError`` naming the choices otherwise."""
    for arm in ARMS:
        if arm.name == name.upper():
            return arm
    choices = ", ".join(arm.name for arm in ARMS)
    raise KeyError(f"unknown arm {name!r}; choose one of {choices}")
