"""Layer: emulator, pure robot model (no I/O). Imports only ``robot.models``.

Forward kinematics by composing the URDF joint transforms, the TCP with a tool offset, Euler
Z-Y-Z angles as the controller reports them, and the TCP's linear and angular velocity.

Reference (docs/emulator.md, "Reference facts the model follows"): each joint's transform is
its origin (translation, then roll-pitch-yaw ``Rz(yaw)·Ry(pitch)·Rx(roll)`` as URDF defines it)
followed by a rotation about its local z; orientation A, B, C is ``R = Rz(A)·Ry(B)·Rz(C)``.

Plain Python floats: a 3×4 rigid transform is a tuple of 12 numbers, row-major ``(R | p)``. Six
joints take a few microseconds this way, and the model needs no numeric library.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final, NamedTuple

from cobot_hmi.emulator.robot.models import RobotModel, Vector3

Transform = tuple[
    float, float, float, float, float, float, float, float, float, float, float, float
]
"""A rigid transform ``(r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz)``."""

IDENTITY: Final[Transform] = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)

GIMBAL_LOCK_SIN: Final = 1e-9
"""Below this |sin B| the Z-Y-Z angles A and C are not separable (see ``euler_zyz_deg``)."""

RAD_PER_DEG: Final = math.pi / 180.0
DEG_PER_RAD: Final = 180.0 / math.pi
"""The factors ``math.radians`` and ``math.degrees`` multiply by (CPython's ``degToRad`` and
``radToDeg``): multiplying by them gives the same bits without a function call per value."""


def compose(a: Transform, b: Transform) -> Transform:
    """``a · b``."""
    a00, a01, a02, ax, a10, a11, a12, ay, a20, a21, a22, az = a
    b00, b01, b02, bx, b10, b11, b12, by, b20, b21, b22, bz = b
    return (
        a00 * b00 + a01 * b10 + a02 * b20,
        a00 * b01 + a01 * b11 + a02 * b21,
        a00 * b02 + a01 * b12 + a02 * b22,
        a00 * bx + a01 * by + a02 * bz + ax,
        a10 * b00 + a11 * b10 + a12 * b20,
        a10 * b01 + a11 * b11 + a12 * b21,
        a10 * b02 + a11 * b12 + a12 * b22,
        a10 * bx + a11 * by + a12 * bz + ay,
        a20 * b00 + a21 * b10 + a22 * b20,
        a20 * b01 + a21 * b11 + a22 * b21,
        a20 * b02 + a21 * b12 + a22 * b22,
        a20 * bx + a21 * by + a22 * bz + az,
    )


def from_rpy(xyz: Vector3, rpy_rad: Vector3) -> Transform:
    """A URDF ``<origin xyz rpy>``: translation, rotation ``Rz(yaw)·Ry(pitch)·Rx(roll)``."""
    roll, pitch, yaw = rpy_rad
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return (
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        xyz[0],
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        xyz[1],
        -sp,
        cp * sr,
        cp * cr,
        xyz[2],
    )


def from_euler_zyz_deg(position_mm: Sequence[float], abc_deg: Sequence[float]) -> Transform:
    """A pose as the controller writes it: position in mm, ``Rz(A)·Ry(B)·Rz(C)`` in degrees."""
    a, b, c = (math.radians(v) for v in abc_deg)
    ca, sa, cb, sb, cc, sc = (
        math.cos(a),
        math.sin(a),
        math.cos(b),
        math.sin(b),
        math.cos(c),
        math.sin(c),
    )
    return (
        ca * cb * cc - sa * sc,
        -ca * cb * sc - sa * cc,
        ca * sb,
        position_mm[0] / 1000.0,
        sa * cb * cc + ca * sc,
        -sa * cb * sc + ca * cc,
        sa * sb,
        position_mm[1] / 1000.0,
        -sb * cc,
        sb * sc,
        cb,
        position_mm[2] / 1000.0,
    )


def euler_zyz_deg(t: Transform) -> Vector3:
    """A, B, C in degrees with ``R = Rz(A)·Ry(B)·Rz(C)``, B in [0, 180].

    At B = 0 or 180 (gimbal lock) only A + C, respectively A − C, is defined; this model then
    reports C = 0 and puts the whole angle in A. Controllers resolve the same ambiguity their own
    way (the M1013's published check shows A = 75, C = 45 where A − C = 30 is all that is
    defined), so a comparison across the lock must compare rotations, not the three numbers.
    """
    r02, r12, r20, r21, r22 = t[2], t[6], t[8], t[9], t[10]
    sin_b = math.hypot(r02, r12)
    b = math.atan2(sin_b, r22)
    if sin_b > GIMBAL_LOCK_SIN:
        a = math.atan2(r12, r02)
        c = math.atan2(r21, -r20)
    else:
        # R = Rz(A ± C)·Ry(B): read the combined angle from the first column and set C = 0.
        c = 0.0
        a = math.atan2(t[4], t[0]) if r22 > 0 else math.atan2(-t[4], -t[0])
    return (a * DEG_PER_RAD, b * DEG_PER_RAD, c * DEG_PER_RAD)


def rotation_angle_deg(a: Transform, b: Transform) -> float:
    """The angle of the rotation that takes ``a``'s orientation to ``b``'s (geodesic distance).

    Read as ``atan2(sin, cos)`` of the relative rotation ``M = Raᵀ·Rb`` (its sine from the
    skew-symmetric part, its cosine from the trace), not ``acos`` of the trace alone: acos is
    flat at 0°, where one rounding (1e-16) in the trace reads as almost 1e-6° between two equal
    rotations (the golden vectors' tolerance, ``codegen/arm_vectors.py``).
    """

    def m(i: int, j: int) -> float:
        return a[i] * b[j] + a[4 + i] * b[4 + j] + a[8 + i] * b[8 + j]

    cos_angle = (m(0, 0) + m(1, 1) + m(2, 2) - 1.0) / 2.0
    sin_angle = math.hypot(m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1)) / 2.0
    return math.degrees(math.atan2(sin_angle, cos_angle))


class Kinematics(NamedTuple):
    """Everything one forward-kinematics pass yields (SI units, base frame)."""

    joint_frames: tuple[Transform, ...]
    """Frame of each moving link (after its joint's rotation), J1 first."""
    tcp: Transform
    """The TCP: the flange frame (link 6) times the tool offset."""


def forward(
    model: RobotModel, joints_deg: Sequence[float], tool: Transform = IDENTITY
) -> Kinematics:
    """Compose the chain base → link 1 → … → link 6 → tool.

    Each step is ``current · origin · Rz(q)``, written out: the rotation about z only mixes the
    first two columns, so it costs a few products instead of a second full composition (this runs
    for every produced frame). The first ``current · origin`` (identity · J1's origin) is the same
    every time: ``_chain`` works it out once, with the same arithmetic.
    """
    first, next_origins = _chain(model)
    frames: list[Transform] = []
    append = frames.append
    cos, sin = math.cos, math.sin
    # a = current · origin of this joint.
    a00, a01, a02, px, a10, a11, a12, py, a20, a21, a22, pz = first
    for q_deg, origin in zip(joints_deg, next_origins, strict=True):
        # r = a · Rz(q): the third column stays a's.
        q = q_deg * RAD_PER_DEG  # = math.radians(q_deg), bit for bit, without the call
        c, s = cos(q), sin(q)
        r00, r01, r02 = a00 * c + a01 * s, a01 * c - a00 * s, a02
        r10, r11, r12 = a10 * c + a11 * s, a11 * c - a10 * s, a12
        r20, r21, r22 = a20 * c + a21 * s, a21 * c - a20 * s, a22
        append((r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz))
        if origin is None:
            break  # the flange
        o00, o01, o02, ox, o10, o11, o12, oy, o20, o21, o22, oz = origin
        # The next joint's a = r · its origin.
        a00 = r00 * o00 + r01 * o10 + r02 * o20
        a01 = r00 * o01 + r01 * o11 + r02 * o21
        a02 = r00 * o02 + r01 * o12 + r02 * o22
        a10 = r10 * o00 + r11 * o10 + r12 * o20
        a11 = r10 * o01 + r11 * o11 + r12 * o21
        a12 = r10 * o02 + r11 * o12 + r12 * o22
        a20 = r20 * o00 + r21 * o10 + r22 * o20
        a21 = r20 * o01 + r21 * o11 + r22 * o21
        a22 = r20 * o02 + r21 * o12 + r22 * o22
        px, py, pz = (
            r00 * ox + r01 * oy + r02 * oz + px,
            r10 * ox + r11 * oy + r12 * oz + py,
            r20 * ox + r21 * oy + r22 * oz + pz,
        )
    flange = frames[-1]
    return Kinematics(tuple(frames), flange if tool is IDENTITY else compose(flange, tool))


_Chain = tuple[Transform, tuple[Transform | None, ...]]

_CHAINS: dict[int, tuple[RobotModel, _Chain]] = {}
"""Per model, by identity (the model is kept, so its id is never reused): identity · J1's origin,
and each next joint's origin (None after J6). Not ``functools.cache``: hashing a model hashes
every nested spec, on every call."""


def _chain(model: RobotModel) -> _Chain:
    """The model's constant joint-origin transforms, computed once."""
    entry = _CHAINS.get(id(model))
    if entry is None or entry[0] is not model:
        origins = [from_rpy(j.origin_xyz_m, j.origin_rpy_rad) for j in model.joints]
        # compose() does forward's arithmetic in forward's order: identity · origin, bit for bit.
        first = compose(IDENTITY, origins[0])
        entry = (model, (first, (*origins[1:], None)))
        _CHAINS[id(model)] = entry
    return entry[1]


def position_mm(t: Transform) -> Vector3:
    return (t[3] * 1000.0, t[7] * 1000.0, t[11] * 1000.0)


def tcp_velocity(kin: Kinematics, joint_velocity_deg_s: Sequence[float]) -> tuple[Vector3, Vector3]:
    """The TCP's linear velocity (mm/s) and angular velocity (degree/s) in the base frame.

    This is the time derivative of the forward-kinematics pose by the chain rule (each joint i
    adds ``z_i × (p_tcp − p_i)·q̇_i`` to the linear and ``z_i·q̇_i`` to the angular velocity), so it
    equals the pose's numerically differentiated rate of change; a test checks that.
    """
    tcp = kin.tcp
    px, py, pz = tcp[3], tcp[7], tcp[11]
    vx = vy = vz = wx = wy = wz = 0.0
    for frame, qd_deg in zip(kin.joint_frames, joint_velocity_deg_s, strict=True):
        if qd_deg == 0.0:
            continue
        qd = qd_deg * RAD_PER_DEG
        _, _, zx, fx, _, _, zy, fy, _, _, zz, fz = frame  # the joint's axis: its frame's z
        rx, ry, rz = px - fx, py - fy, pz - fz
        # z × r, written out: this runs for every produced frame.
        vx, vy, vz = (
            vx + (zy * rz - zz * ry) * qd,
            vy + (zz * rx - zx * rz) * qd,
            vz + (zx * ry - zy * rx) * qd,
        )
        wx, wy, wz = wx + zx * qd, wy + zy * qd, wz + zz * qd
    return (
        (vx * 1000.0, vy * 1000.0, vz * 1000.0),
        (wx * DEG_PER_RAD, wy * DEG_PER_RAD, wz * DEG_PER_RAD),
    )
