"""Layer: emulator, pure robot model (no I/O, no sockets). Imports nothing of the project.

The two arms the emulator can be: their URDF joint chain (origins, limits) and the link masses the
gravity model needs, as data.

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

Acceleration limits, torque constants, friction and thermal figures are not published: they are
plausible values chosen for a convincing demo, marked as such.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

Vector3 = tuple[float, float, float]

_HALF_PI: Final = math.pi / 2


@dataclass(frozen=True, slots=True)
class JointSpec:
    """One revolute joint: its URDF origin in the parent link frame and its limits.

    Every joint of these arms turns about the local z axis of its child link frame.
    """

    origin_xyz_m: Vector3
    origin_rpy_rad: Vector3
    limit_deg: float
    """Symmetric position limit: the joint stays within ±limit_deg."""
    max_speed_deg_s: float
    max_accel_deg_s2: float
    """Not published: chosen (about four times the speed limit per second)."""
    torque_per_amp_nm: float
    """Joint-side torque per motor ampere (motor constant × gear ratio). Not published: chosen."""
    viscous_friction_nm_s_deg: float
    """Friction torque per degree/s. Not published: chosen."""
    reflected_inertia_kg_m2: float
    """Motor and gear inertia seen at the joint. Not published: chosen."""
    rated_current_a: float
    """Current at which the motor settles ``MotorThermal``'s rated rise above room. Chosen."""


@dataclass(frozen=True, slots=True)
class LinkInertia:
    """The mass of the link a joint moves and its centre of mass in that link's frame."""

    mass_kg: float
    com_m: Vector3


@dataclass(frozen=True, slots=True)
class RobotModel:
    """An arm: six joints, the six links they move, and the demo program's waypoints."""

    name: str
    joints: tuple[JointSpec, ...]
    links: tuple[LinkInertia, ...]
    demo_waypoints_deg: tuple[tuple[float, ...], ...]
    """Joint positions the demo program visits in turn (all inside the limits)."""


def _joint(
    xyz: Vector3, rpy: Vector3, limit_deg: float, speed_deg_s: float, big_motor: bool
) -> JointSpec:
    return JointSpec(
        origin_xyz_m=xyz,
        origin_rpy_rad=rpy,
        limit_deg=limit_deg,
        max_speed_deg_s=speed_deg_s,
        max_accel_deg_s2=4.0 * speed_deg_s,
        torque_per_amp_nm=12.0 if big_motor else 4.0,
        viscous_friction_nm_s_deg=0.05 if big_motor else 0.01,
        reflected_inertia_kg_m2=0.8 if big_motor else 0.1,
        rated_current_a=8.0 if big_motor else 2.5,
    )


# Waypoints shared by both arms: a pick-and-place tour that stays far from the limits of either.
_DEMO_WAYPOINTS_DEG: Final = (
    (0.0, 0.0, 90.0, 0.0, 90.0, 0.0),  # home
    (35.0, 20.0, 70.0, 10.0, 85.0, 30.0),  # above the pick station
    (35.0, 32.0, 78.0, 10.0, 65.0, 30.0),  # pick
    (-40.0, 10.0, 100.0, -20.0, 70.0, -60.0),  # transfer
    (-40.0, 28.0, 85.0, -20.0, 65.0, -60.0),  # place
)

M1013: Final = RobotModel(
    name="M1013",
    joints=(
        _joint((0.0, 0.0, 0.1525), (0.0, 0.0, 0.0), 360.0, 120.0, True),
        _joint((0.0, 0.0345, 0.0), (0.0, -_HALF_PI, -_HALF_PI), 360.0, 120.0, True),
        _joint((0.620, 0.0, 0.0), (0.0, 0.0, _HALF_PI), 160.0, 180.0, True),
        _joint((0.0, -0.559, 0.0), (_HALF_PI, 0.0, 0.0), 360.0, 225.0, False),
        _joint((0.0, 0.0, 0.0), (-_HALF_PI, 0.0, 0.0), 360.0, 225.0, False),
        _joint((0.0, -0.121, 0.0), (_HALF_PI, 0.0, 0.0), 360.0, 225.0, False),
    ),
    links=(
        LinkInertia(7.8, (0.000119, 0.0428, -0.006383)),
        LinkInertia(10.83, (0.25973, -5.3e-05, 0.15782)),
        LinkInertia(3.68, (-1.5e-05, -0.006702, 0.044608)),
        LinkInertia(3.82, (7.1e-05, 0.091879, -0.18252)),
        LinkInertia(2.82, (-0.000273, 0.003651, 0.032088)),
        LinkInertia(1.16, (-0.000292, 7e-06, -0.0539)),
    ),
    demo_waypoints_deg=_DEMO_WAYPOINTS_DEG,
)

M0609: Final = RobotModel(
    name="M0609",
    joints=(
        _joint((0.0, 0.0, 0.1345), (0.0, 0.0, 0.0), 360.0, 150.0, True),
        _joint((0.0, 0.0062, 0.0), (0.0, -_HALF_PI, -_HALF_PI), 360.0, 150.0, True),
        _joint((0.411, 0.0, 0.0), (0.0, 0.0, _HALF_PI), 150.0, 180.0, True),
        _joint((0.0, -0.368, 0.0), (_HALF_PI, 0.0, 0.0), 360.0, 225.0, False),
        _joint((0.0, 0.0, 0.0), (-_HALF_PI, 0.0, 0.0), 360.0, 225.0, False),
        _joint((0.0, -0.121, 0.0), (_HALF_PI, 0.0, 0.0), 360.0, 225.0, False),
    ),
    links=(
        LinkInertia(5.02, (7.2e-05, 0.036227, -0.003417)),
        LinkInertia(8.04, (0.20447, 2.6e-05, 0.16005)),
        LinkInertia(3.6, (-2.2e-05, -0.006867, 0.043445)),
        LinkInertia(3.57, (4e-05, 0.097079, -0.10981)),
        LinkInertia(2.83, (-6.8e-05, 0.003827, 0.031969)),
        LinkInertia(1.16, (-3e-05, -4.5e-05, -0.0539)),
    ),
    demo_waypoints_deg=_DEMO_WAYPOINTS_DEG,
)

MODELS: Final = {model.name: model for model in (M1013, M0609)}
"""The selectable arms by name; M1013 is the default."""

DEFAULT_MODEL: Final = M1013


def model_by_name(name: str) -> RobotModel:
    """The arm called ``name`` (case-insensitive); ``KeyError`` naming the choices otherwise."""
    try:
        return MODELS[name.upper()]
    except KeyError:
        raise KeyError(f"unknown robot model {name!r}; choose one of {', '.join(MODELS)}") from None
