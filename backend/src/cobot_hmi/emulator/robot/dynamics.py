"""Layer: emulator, pure robot model (no I/O). Imports only ``robot.models``, ``robot.kinematics``,
``robot.wear``.

"Dynamics-ish" monitoring values: believable, consistent with the motion, not a full rigid-body
model. Joint torque is what the motor must give: gravity (every link's mass at its URDF centre of
mass, plus the payload at the TCP) plus an inertia term (the masses beyond the joint as points at
their distance from its axis, plus the motor's reflected inertia, times the joint's acceleration)
plus viscous friction. Motor current is torque over the joint's torque constant, plus noise. Motor
temperature approaches, first-order, a level that rises with the square of the current (copper
losses), starting at room temperature. Wear (``robot.wear``) adds friction to the torque
(``worn_torques``) and heat to a motor's settling level.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final, NamedTuple

from cobot_hmi.emulator.robot.kinematics import RAD_PER_DEG, Kinematics
from cobot_hmi.emulator.robot.models import RobotModel
from cobot_hmi.emulator.robot.wear import Wear

GRAVITY_M_S2: Final = 9.80665


class _ModelConstants(NamedTuple):
    joints: tuple[tuple[float, float, float, float, float, float], ...]
    """Each joint's link mass, centre of mass (x, y, z), reflected inertia and friction."""
    torque_per_amp_nm: tuple[float, ...]


_CONSTANTS: dict[int, tuple[RobotModel, _ModelConstants]] = {}
"""Per model (by identity, the model kept so its id is never reused): the joint and link figures
the per-frame functions need, read once instead of per frame."""


def _constants(model: RobotModel) -> _ModelConstants:
    entry = _CONSTANTS.get(id(model))
    if entry is None or entry[0] is not model:
        values = _ModelConstants(
            tuple(
                (
                    link.mass_kg,
                    *link.com_m,
                    spec.reflected_inertia_kg_m2,
                    spec.viscous_friction_nm_s_deg,
                )
                for link, spec in zip(model.links, model.joints, strict=True)
            ),
            tuple(spec.torque_per_amp_nm for spec in model.joints),
        )
        entry = _CONSTANTS[id(model)] = (model, values)
    return entry[1]


def joint_torques(
    model: RobotModel,
    kin: Kinematics,
    velocity_deg_s: Sequence[float],
    acceleration_deg_s2: Sequence[float],
    payload_kg: float = 0.0,
) -> tuple[float, ...]:
    """Torque (N·m) each joint's motor gives to hold and move the arm as it is moving.

    Joint i moves links i..6 and the payload. With suffix sums over those bodies of the mass M,
    the first moment S = Σ m·c and the second moment Q = Σ m·c·cᵀ, the gravity torque about the
    axis z through p is ``z · ((S − M·p) × (0, 0, −g))`` and the point masses' inertia about it
    is ``Σ m·|c − p|² − Σ m·(z·(c − p))²``, both expanded so one pass over the bodies serves
    every joint.
    """
    mass = 0.0
    sx = sy = sz = 0.0
    qxx = qyy = qzz = qxy = qxz = qyz = 0.0
    # Q only feeds the inertia term: without any acceleration (at rest, cruising) skip its sums.
    # (m·c_x·c_y is (m·c_x)·c_y as Python evaluates it, so m·c is worked out once per body.)
    any_acceleration = any(acceleration_deg_s2)
    if payload_kg > 0.0:
        # The payload moves with the last link: fold it into link 6's sums.
        m, cx, cy, cz = payload_kg, kin.tcp[3], kin.tcp[7], kin.tcp[11]
        mass += m
        mcx, mcy, mcz = m * cx, m * cy, m * cz
        sx, sy, sz = sx + mcx, sy + mcy, sz + mcz
        if any_acceleration:
            qxx, qyy, qzz = qxx + mcx * cx, qyy + mcy * cy, qzz + mcz * cz
            qxy, qxz, qyz = qxy + mcx * cy, qxz + mcx * cz, qyz + mcy * cz
    frames = kin.joint_frames
    constants = _constants(model).joints
    count = len(constants)
    torques = [0.0] * count
    # From the last link to the first: the sums then hold exactly the bodies joint i moves.
    for i in range(count - 1, -1, -1):
        m, lx, ly, lz, reflected_inertia_kg_m2, friction_nm_s_deg = constants[i]
        f00, f01, zx, px, f10, f11, zy, py, f20, f21, zz, pz = frames[i]
        # The link's centre of mass in the base frame (its frame's z column is the joint axis).
        cx = f00 * lx + f01 * ly + zx * lz + px
        cy = f10 * lx + f11 * ly + zy * lz + py
        cz = f20 * lx + f21 * ly + zz * lz + pz
        mass += m
        mcx, mcy, mcz = m * cx, m * cy, m * cz
        sx, sy, sz = sx + mcx, sy + mcy, sz + mcz
        if any_acceleration:
            qxx, qyy, qzz = qxx + mcx * cx, qyy + mcy * cy, qzz + mcz * cz
            qxy, qxz, qyz = qxy + mcx * cy, qxz + mcx * cz, qyz + mcy * cz
        # First moment about p: S − M·p; its cross product with (0, 0, −g), dotted with z.
        rx, ry = sx - mass * px, sy - mass * py
        gravity_nm = GRAVITY_M_S2 * (zx * ry - zy * rx)
        acceleration = acceleration_deg_s2[i]
        if not acceleration:  # no inertia term to work out (at rest, cruising)
            torques[i] = gravity_nm + friction_nm_s_deg * velocity_deg_s[i]
            continue
        # Σ m|c − p|² and Σ m(z·(c − p))² from the moments.
        trace_q = qxx + qyy + qzz
        s_dot_p = sx * px + sy * py + sz * pz
        p_sq = px * px + py * py + pz * pz
        radial = trace_q - 2.0 * s_dot_p + mass * p_sq
        zqz = (
            zx * zx * qxx
            + zy * zy * qyy
            + zz * zz * qzz
            + 2.0 * (zx * zy * qxy + zx * zz * qxz + zy * zz * qyz)
        )
        z_dot_s = zx * sx + zy * sy + zz * sz
        z_dot_p = zx * px + zy * py + zz * pz
        axial = zqz - 2.0 * z_dot_p * z_dot_s + mass * z_dot_p * z_dot_p
        beyond_kg_m2 = radial - axial
        # max(0.0, x) and math.radians, written out (same values, no calls).
        inertia_kg_m2 = reflected_inertia_kg_m2 + (beyond_kg_m2 if beyond_kg_m2 > 0.0 else 0.0)
        torques[i] = (
            gravity_nm
            + inertia_kg_m2 * (acceleration * RAD_PER_DEG)
            + friction_nm_s_deg * velocity_deg_s[i]
        )
    return tuple(torques)


def worn_torques(
    model: RobotModel,
    wear: Wear,
    torques_nm: Sequence[float],
    velocity_deg_s: Sequence[float],
    *,
    temperatures_c: Sequence[float],
    now_s: float,
) -> tuple[float, ...]:
    """The torques with the friction the wear adds (the healthy friction is in ``torques_nm``)."""
    return tuple(
        torque + wear.friction_nm(j, v, t, spec.viscous_friction_nm_s_deg, now_s)
        for j, (torque, v, t, spec) in enumerate(
            zip(torques_nm, velocity_deg_s, temperatures_c, model.joints, strict=True)
        )
    )


def motor_currents(
    model: RobotModel, torques_nm: Sequence[float], noise_a: Sequence[float]
) -> tuple[float, ...]:
    """Motor current (A): torque over the joint's torque constant, plus the given noise."""
    return tuple(
        [
            torque / torque_per_amp_nm + noise
            for torque, torque_per_amp_nm, noise in zip(
                torques_nm, _constants(model).torque_per_amp_nm, noise_a, strict=True
            )
        ]
    )


class MotorThermal:
    """Motor temperatures: first-order approach to room + rise·(I / I_rated)²."""

    def __init__(
        self,
        model: RobotModel,
        room_temperature_c: float,
        time_constant_s: float,
        rise_at_rated_current_c: float,
    ) -> None:
        self.rated_current_a = tuple(spec.rated_current_a for spec in model.joints)
        self.room_temperature_c = room_temperature_c
        self.time_constant_s = time_constant_s
        self.rise_at_rated_current_c = rise_at_rated_current_c
        self.temperatures_c: tuple[float, ...] = (room_temperature_c,) * len(model.joints)

    def steady_state_c(self, currents_a: Sequence[float]) -> tuple[float, ...]:
        """The temperature each motor would settle at if these currents lasted."""
        return tuple(
            self.room_temperature_c + self.rise_at_rated_current_c * (current / rated) ** 2
            for current, rated in zip(currents_a, self.rated_current_a, strict=True)
        )

    def update(
        self, currents_a: Sequence[float], dt_s: float, extra_c: Sequence[float] | None = None
    ) -> tuple[float, ...]:
        """Advance ``dt_s`` seconds under ``currents_a`` (exact for a constant current);
        ``extra_c``: degrees each motor settles above what its current explains (a worn
        motor, ``Wear.extra_heat_c``)."""
        if dt_s > 0.0:
            keep = math.exp(-dt_s / self.time_constant_s)
            room_c, rise_c = self.room_temperature_c, self.rise_at_rated_current_c
            # steady_state_c inlined, as a plain loop (this runs every step; a comprehension costs
            # more for six values): target + (temperature − target)·keep.
            temperatures_c: list[float] = []
            append = temperatures_c.append
            for temperature, current, rated in zip(
                self.temperatures_c, currents_a, self.rated_current_a, strict=True
            ):
                target_c = room_c + rise_c * (current / rated) ** 2
                append(target_c + (temperature - target_c) * keep)
            if extra_c is not None:
                temperatures_c = [
                    t + e * (1.0 - keep) for t, e in zip(temperatures_c, extra_c, strict=True)
                ]
            self.temperatures_c = tuple(temperatures_c)
        return self.temperatures_c
