"""Hand-built golden vectors, independent of the codec.

Each vector is built with ``struct.pack_into`` at the literal offsets of the robot's I/O
table (docs/assembly.md) and carries the JSON the table says it decodes to, written out from
the same literal inputs. Nothing here imports the layout or the codec: the codec is checked
against this, not mirrored by it. ``python tests/golden_vectors.py`` rewrites ``tests/golden/``.
"""

from __future__ import annotations

import json
import math
import struct
import sys
from dataclasses import dataclass
from pathlib import Path

GOLDEN_DIR = Path(__file__).parent / "golden"

STATE_NAMES = (
    "EMERGENCY_STOP INITIALIZING SAFE_OFF INTERRUPTED MANUAL_STANDBY MANUAL_JOGGING "
    "MANUAL_HANDGUIDING RECOVERY_STANDBY RECOVERY_JOGGING BACKDRIVE_HOLD BACKDRIVE_RELEASE "
    "BACKDRIVE_RELEASE_BY_COCKPIT RECOVERY_HANDGUIDING STANDALONE_STANDBY STANDALONE_RUNNING "
    "COLLABORATIVE_STANDBY COLLABORATIVE_RUNNING HIGH_PRIORITY_RUNNING AUTO_MEASURE "
    "HANDGUIDING_CONTROL_STANDBY HANDGUIDING_CONTROL_RUNNING"
).split()

# (name, offset) of the spec's REAL triples and sextuples in T→O.
T2O_REALS = (
    ("joint_position", 36, 6),
    ("joint_velocity", 60, 6),
    ("joint_motor_current", 84, 6),
    ("joint_motor_temperature", 108, 6),
    ("joint_torque", 132, 6),
    ("joint_external_torque", 156, 6),
    ("tcp_position", 180, 3),
    ("tcp_orientation", 192, 3),
    ("tcp_velocity", 204, 3),
    ("tcp_angular_velocity", 216, 3),
    ("tool_offset_position", 228, 3),
    ("tool_offset_orientation", 240, 3),
    ("external_force", 252, 3),
    ("external_moment", 264, 3),
)


@dataclass(frozen=True)
class Vector:
    name: str
    wire: bytes
    expected_json: dict[str, object]


def _f32(value: float) -> float | None:
    """What a REAL reads back as in JSON: float32-rounded, non-finite as null."""
    if not math.isfinite(value):
        return None
    rounded: float = struct.unpack("<f", struct.pack("<f", value))[0]
    return rounded


def _bits(word: int, first: int, count: int) -> list[bool]:
    return [bool(word >> (first + i) & 1) for i in range(count)]


def t2o_vector(
    name: str,
    *,
    di: int,
    do: int,
    aio_type: int,
    analog: tuple[float, float, float, float],
    tool_di: int,
    tool_do: int,
    version: tuple[int, int, int],
    state: int,
    flags: int,
    reals: dict[str, list[float]],
    bit_out: int,
) -> Vector:
    """A 284-byte T→O frame from literal values, and its expected JSON."""
    wire = bytearray(284)
    struct.pack_into("<HH", wire, 0, di, do)  # word 0: DI bits 0-15, DO bits 16-31
    struct.pack_into("<I", wire, 4, aio_type)  # word 4 bits 0-3: In0, In1, Out0, Out1
    struct.pack_into("<4f", wire, 8, *analog)  # AI0 @8, AI1 @12, AO0 @16, AO1 @20
    struct.pack_into("<I", wire, 24, tool_di | tool_do << 16)  # tool DI 0-5, tool DO 16-21
    struct.pack_into("<3B", wire, 28, *version)
    struct.pack_into("<B", wire, 32, state)
    struct.pack_into("<B", wire, 34, flags)  # word 32 bits 16-20 = byte 34 bits 0-4
    for field, offset, count in T2O_REALS:
        struct.pack_into(f"<{count}f", wire, offset, *reals[field])
    struct.pack_into("<Q", wire, 276, bit_out)  # registers 0-31 @276, 32-63 @280
    expected: dict[str, object] = {
        "controlbox_di": _bits(di, 0, 16),
        "controlbox_do": _bits(do, 0, 16),
        "analog_input_type": [aio_type & 1, aio_type >> 1 & 1],
        "analog_output_type": [aio_type >> 2 & 1, aio_type >> 3 & 1],
        "analog_input": [_f32(analog[0]), _f32(analog[1])],
        "analog_output": [_f32(analog[2]), _f32(analog[3])],
        "tool_di": _bits(tool_di, 0, 6),
        "tool_do": _bits(tool_do, 0, 6),
        "controller_version": dict(zip(("major", "minor", "patch"), version, strict=True)),
        "robot_state": state,
        "robot_state_name": STATE_NAMES[state] if state < len(STATE_NAMES) else "UNKNOWN",
        "servo_on": bool(flags & 1),
        "safety_stopped": bool(flags & 2),
        "emergency_stopped": bool(flags & 4),
        "direct_teach_button_pressed": bool(flags & 8),
        "power_button_pressed": bool(flags & 16),
    }
    for field, _, _ in T2O_REALS:
        expected[field] = [_f32(v) for v in reals[field]]
    expected["bit_output_registers"] = _bits(bit_out, 0, 64)
    return Vector(name, bytes(wire), expected)


def o2t_vector(
    name: str, *, do: int, tool_do: int, ao_type: int, analog: tuple[float, float], bit_in: int
) -> Vector:
    """A 20-byte O→T command image from literal values, and its expected JSON."""
    wire = bytearray(20)
    struct.pack_into("<I", wire, 0, do | tool_do << 16 | ao_type << 24)
    struct.pack_into("<2f", wire, 4, *analog)
    struct.pack_into("<Q", wire, 12, bit_in)
    expected: dict[str, object] = {
        "controlbox_do": _bits(do, 0, 16),
        "tool_do": _bits(tool_do, 0, 6),
        "analog_output_type": [ao_type & 1, ao_type >> 1 & 1],
        "analog_output": [_f32(analog[0]), _f32(analog[1])],
        "bit_input_registers": _bits(bit_in, 0, 64),
    }
    return Vector(name, bytes(wire), expected)


def _reals(fill: float) -> dict[str, list[float]]:
    return {field: [fill] * count for field, _, count in T2O_REALS}


def _mid_motion_reals() -> dict[str, list[float]]:
    return {
        "joint_position": [30.5, -12.25, 95.0, 0.75, 88.5, -45.125],
        "joint_velocity": [12.0, -3.5, 20.25, 0.0, -8.0, 45.5],
        "joint_motor_current": [1.25, 3.5, 2.0, 0.375, 0.5, 0.125],
        "joint_motor_temperature": [31.5, 38.25, 35.0, 29.75, 28.5, 27.0],
        "joint_torque": [2.5, 61.75, 24.5, 1.25, 3.0, 0.25],
        "joint_external_torque": [0.125, -0.5, 0.25, 0.0, -0.0625, 0.03125],
        "tcp_position": [466.9, 309.4, 651.5],
        "tcp_orientation": [75.0, 180.0, 45.0],
        "tcp_velocity": [120.5, -40.25, 3.0],
        "tcp_angular_velocity": [1.5, -2.25, 10.0],
        "tool_offset_position": [0.0, 0.0, 150.0],
        "tool_offset_orientation": [0.0, 0.0, 90.0],
        "external_force": [1.5, -0.75, 12.25],
        "external_moment": [0.125, 0.25, -0.5],
    }


def t2o_vectors() -> list[Vector]:
    extreme = _reals(3.4028234663852886e38)  # largest finite float32
    extreme["joint_position"] = [math.nan, math.inf, -math.inf, -3.4028234663852886e38,
                                 1.401298464324817e-45, -0.0]  # fmt: skip
    extreme["tcp_position"] = [math.nan, -math.inf, math.inf]
    return [
        t2o_vector(
            "t2o_all_zero",
            di=0,
            do=0,
            aio_type=0,
            analog=(0.0, 0.0, 0.0, 0.0),
            tool_di=0,
            tool_do=0,
            version=(0, 0, 0),
            state=0,
            flags=0,
            reals=_reals(0.0),
            bit_out=0,
        ),
        t2o_vector(
            "t2o_mid_motion",
            di=0b0000_0000_0000_0101,  # DI 1 (part present) and DI 3
            do=0b0000_0000_0000_0100,  # DO 3
            aio_type=0b0110,  # In1 voltage, Out0 voltage
            analog=(12.5, 4.75, 5.0, 4.0),
            tool_di=0b000010,  # tool DI 2
            tool_do=0b100001,  # tool DO 1 and 6
            version=(2, 12, 3),
            state=14,  # STANDALONE_RUNNING
            flags=0b00001,  # servo on
            reals=_mid_motion_reals(),
            bit_out=(1 << 40) | (1 << 0) | (1 << 63),
        ),
        t2o_vector(
            "t2o_every_bit_extreme",
            di=0xFFFF,
            do=0xFFFF,
            aio_type=0xF,
            analog=(math.nan, math.inf, -math.inf, -3.4028234663852886e38),
            tool_di=0x3F,
            tool_do=0x3F,
            version=(255, 255, 255),
            state=255,  # not in the table: UNKNOWN
            flags=0x1F,
            reals=extreme,
            bit_out=(1 << 64) - 1,
        ),
    ]


def o2t_vectors() -> list[Vector]:
    return [
        o2t_vector("o2t_all_zero", do=0, tool_do=0, ao_type=0, analog=(0.0, 0.0), bit_in=0),
        o2t_vector(
            "o2t_commissioning",
            do=0b0000_0000_0000_0100,  # DO 3
            tool_do=0b000001,  # tool DO 1
            ao_type=0b01,  # AO 0 voltage, AO 1 current
            analog=(7.5, 12.0),
            bit_in=1 << 40,
        ),
        o2t_vector(
            "o2t_every_bit_extreme",
            do=0xFFFF,
            tool_do=0x3F,
            ao_type=0b11,
            analog=(math.nan, -math.inf),
            bit_in=(1 << 64) - 1,
        ),
    ]


def write_golden_files() -> None:
    GOLDEN_DIR.mkdir(exist_ok=True)
    for vector in [*t2o_vectors(), *o2t_vectors()]:
        (GOLDEN_DIR / f"{vector.name}.hex").write_text(vector.wire.hex() + "\n")
        text = json.dumps(vector.expected_json, indent=1, allow_nan=False)
        (GOLDEN_DIR / f"{vector.name}.json").write_text(text + "\n")


if __name__ == "__main__":
    write_golden_files()
    sys.exit(0)
