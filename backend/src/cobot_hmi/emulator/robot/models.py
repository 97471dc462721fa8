"""Layer: emulator, pure robot model (no I/O, no sockets). Imports only ``cobot_hmi.arms``.

The two arms the emulator can be: their URDF joint chain (origins, limits) and the link masses the
gravity model needs. The published geometry lives once in ``cobot_hmi.arms`` (which the panel's 3D
view is generated from); this module adds what a simulation needs beyond it.

Acceleration limits, torque constants, friction and thermal figures are not published: they are
plausible values chosen for a convincing demo, marked as such.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from cobot_hmi.arms import M0609_ARM, M1013_ARM, Arm, ArmLink, Vector3

__all__ = [
    "DEFAULT_MODEL",
    "M0609",
    "M1013",
    "MODELS",
    "JointSpec",
    "LinkInertia",
    "RobotModel",
    "Vector3",
    "model_by_name",
]


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


LinkInertia = ArmLink
"""The mass of the link a joint moves and its centre of mass in that link's frame."""


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


def _model(arm: Arm) -> RobotModel:
    """The arm's published geometry with the simulation's chosen figures: J1–J3 have the big
    motors."""
    return RobotModel(
        name=arm.name,
        joints=tuple(
            _joint(j.origin_xyz_m, j.origin_rpy_rad, j.limit_deg, j.max_speed_deg_s, i < 3)
            for i, j in enumerate(arm.joints)
        ),
        links=arm.links,
        demo_waypoints_deg=_DEMO_WAYPOINTS_DEG,
    )


M1013: Final = _model(M1013_ARM)
M0609: Final = _model(M0609_ARM)

MODELS: Final = {model.name: model for model in (M1013, M0609)}
"""The selectable arms by name; M1013 is the default."""

DEFAULT_MODEL: Final = M1013


def model_by_name(name: str) -> RobotModel:
    """The arm called ``name`` (case-insensitive); ``KeyError`` naming the choices otherwise."""
    try:
        return MODELS[name.upper()]
    except KeyError:
        raise KeyError(f"unknown robot model {name!r}; choose one of {', '.join(MODELS)}") from None
