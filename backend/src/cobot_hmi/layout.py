"""Layer: layout (the bottom of the stack). Imports nothing of the project.

The robot's two EtherNet/IP I/O assemblies, its robot-state enum and its five flags, as data.
This is the only place in the project where an offset, a field name or a state value is written:
the codec, the emulator, the frontend's types and ``docs/assembly.md`` all derive from it
(``cobot_hmi.codegen`` writes the derived files). The "Reading decisions" of
docs/assembly.md are encoded here as data, so a reading found wrong against a real
controller is a one-line fix.

Conventions (CIP): little-endian; ``REAL`` is IEEE-754 binary32; bit *n* of the word at byte
offset *o* is bit *n mod 8* of byte *o + n div 8*.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Final

LAYOUT_VERSION: Final = 1
"""Bumped whenever a field, an offset or the state enum changes; sent to every client."""


class Direction(StrEnum):
    """ODVA's words: T→O is robot (target) to PLC (originator), O→T the other way."""

    T_TO_O = "T2O"
    O_TO_T = "O2T"


class CipType(StrEnum):
    """Element types, named as the CIP specification writes them."""

    BOOL = "BOOL"  # one bit, packed inside a 32-bit word
    USINT = "USINT"  # 8-bit unsigned
    REAL = "REAL"  # IEEE-754 binary32


CIP_TYPE_SIZE_BYTES: Final = {CipType.USINT: 1, CipType.REAL: 4}


@dataclass(frozen=True, slots=True)
class FlagInfo:
    """A status flag as the user's table abbreviates and names it."""

    abbreviation: str
    full_name: str


@dataclass(frozen=True, slots=True)
class Field:
    """One named field of an assembly.

    ``offset`` is the byte offset of the element (or, for packed ``BOOL`` bits, of the 32-bit
    word that holds them, as the spec's table is drawn); ``first_bit`` is the bit within that
    word where the field starts, so the field covers bits ``first_bit .. first_bit + count - 1``.
    A field with ``scalar`` set decodes to one value instead of a list of ``count`` values.
    ``value_names`` marks a coded field (0 = current, 1 = voltage) that decodes to an integer;
    ``element_names`` marks a record (the controller version) that decodes to an object.
    """

    name: str
    direction: Direction
    offset: int
    cip_type: CipType
    count: int
    description: str
    group: str
    unit: str = ""
    first_bit: int | None = None
    scalar: bool = False
    channels: tuple[str, ...] = ()
    value_names: tuple[str, ...] = ()
    element_names: tuple[str, ...] = ()
    flag: FlagInfo | None = None
    enum: str | None = None

    @property
    def bit_count(self) -> int:
        """Bits the field occupies on the wire."""
        if self.cip_type is CipType.BOOL:
            return self.count
        return self.count * CIP_TYPE_SIZE_BYTES[self.cip_type] * 8

    @property
    def first_wire_bit(self) -> int:
        """Absolute bit position (offset·8 + bit) of the field's first bit in the assembly."""
        return self.offset * 8 + (self.first_bit or 0)

    @property
    def value_kind(self) -> str:
        """How a decoded element is typed: ``bool``, ``int`` or ``float``."""
        if self.cip_type is CipType.REAL:
            return "float"
        if self.cip_type is CipType.BOOL and not self.value_names:
            return "bool"
        return "int"


@dataclass(frozen=True, slots=True)
class RobotStateInfo:
    """One value of the robot-state enum (T→O byte 32) as the user's table defines it.

    ``pendant_colours`` is the teach pendant's colour semantics; more than one colour means they
    are shown in turn. ``colour_from_table`` says whether the user's table states the colour
    (standalone, collaborative, high-priority zones) or it is this project's reading of the
    state's severity, to be checked against a real pendant.
    """

    value: int
    name: str
    description: str
    pendant_colours: tuple[str, ...]
    colour_from_table: bool = False
    label: str = ""
    """The state in plain words for people ("Standalone running"); the enum ``name`` stays the
    identifier (API, tooltips)."""


@dataclass(frozen=True, slots=True)
class Assembly:
    """An assembly object instance: which direction it carries, its data size and its fields."""

    name: str
    direction: Direction
    size_bytes: int
    default_instance: int
    description: str
    fields: tuple[Field, ...]


def numbered(prefix: str, first: int, count: int) -> tuple[str, ...]:
    """Channel labels as the robot prints them: ``numbered("DI", 1, 3)`` → DI 1, DI 2, DI 3."""
    return tuple(f"{prefix} {first + i}" for i in range(count))


_T2O = Direction.T_TO_O
_O2T = Direction.O_TO_T
_XYZ: Final = ("X", "Y", "Z")
_ABC: Final = ("A", "B", "C")
_JOINTS: Final = numbered("J", 1, 6)
_ANALOG_TYPE_CODING: Final = ("current", "voltage")  # Doosan's Modbus coding, spec note on AIO type


def _joint_reals(name: str, offset: int, what: str, unit: str) -> Field:
    return Field(
        name, _T2O, offset, CipType.REAL, 6, f"Joint 1–6 {what}", "Joint", unit, channels=_JOINTS
    )


def _vector(name: str, offset: int, what: str, unit: str, axes: tuple[str, ...]) -> Field:
    return Field(name, _T2O, offset, CipType.REAL, 3, what, "TCP", unit, channels=axes)


def _flag(name: str, bit: int, abbreviation: str, full_name: str, what: str) -> Field:
    return Field(
        name,
        _T2O,
        32,
        CipType.BOOL,
        1,
        what,
        "Robot",
        first_bit=bit,
        scalar=True,
        flag=FlagInfo(abbreviation, full_name),
    )


# fmt: off
T2O_FIELDS: Final[tuple[Field, ...]] = (
    Field("controlbox_di", _T2O, 0, CipType.BOOL, 16, "ControlBox digital inputs 1–16", "I/O",
          first_bit=0, channels=numbered("DI", 1, 16)),
    Field("controlbox_do", _T2O, 0, CipType.BOOL, 16,
          "ControlBox digital outputs 1–16 (actual state)", "I/O",
          first_bit=16, channels=numbered("DO", 1, 16)),
    Field("analog_input_type", _T2O, 4, CipType.BOOL, 2, "Analog input type: In0, In1", "I/O",
          first_bit=0, channels=numbered("AI", 0, 2), value_names=_ANALOG_TYPE_CODING),
    Field("analog_output_type", _T2O, 4, CipType.BOOL, 2, "Analog output type: Out0, Out1",
          "I/O", first_bit=2, channels=numbered("AO", 0, 2), value_names=_ANALOG_TYPE_CODING),
    Field("analog_input", _T2O, 8, CipType.REAL, 2, "Analog inputs 0–1", "I/O",
          "mA or V per its type", channels=numbered("AI", 0, 2)),
    Field("analog_output", _T2O, 16, CipType.REAL, 2, "Analog outputs 0–1 (actual)", "I/O",
          "mA or V per its type", channels=numbered("AO", 0, 2)),
    # Spec note A: the export shifted this row; tool DI is bits 0–5 and tool DO bits 16–21.
    Field("tool_di", _T2O, 24, CipType.BOOL, 6, "Tool digital inputs 1–6", "I/O",
          first_bit=0, channels=numbered("Tool DI", 1, 6)),
    Field("tool_do", _T2O, 24, CipType.BOOL, 6, "Tool digital outputs 1–6 (actual state)", "I/O",
          first_bit=16, channels=numbered("Tool DO", 1, 6)),
    # Spec note B: the patch version is read as a whole byte.
    Field("controller_version", _T2O, 28, CipType.USINT, 3,
          "Controller version: major, minor, patch", "Robot",
          element_names=("major", "minor", "patch")),
    Field("robot_state", _T2O, 32, CipType.USINT, 1, "Robot state (see the state enum)",
          "Robot", scalar=True, enum="RobotState"),
    # Flag order as the user's table has it (SO, SS, ES), not Doosan's Modbus order.
    _flag("servo_on", 16, "SO", "SERVO_ON_ROBOT", "Servo on"),
    _flag("safety_stopped", 17, "SS", "SAFETY_STOPPED", "Safety stopped"),
    _flag("emergency_stopped", 18, "ES", "EMERGENCY_STOPPED", "Emergency stopped"),
    _flag("direct_teach_button_pressed", 19, "DTBP", "DIRECT_TEACH_BUTTON_PRESSED",
          "Direct-teach button pressed"),
    _flag("power_button_pressed", 20, "PBP", "POWER_BUTTON_PRESSED", "Power button pressed"),
    _joint_reals("joint_position", 36, "position", "degree"),
    _joint_reals("joint_velocity", 60, "velocity", "degree/s"),
    _joint_reals("joint_motor_current", 84, "motor current", "A"),
    _joint_reals("joint_motor_temperature", 108, "motor temperature", "°C"),
    _joint_reals("joint_torque", 132, "torque", "N·m"),
    _joint_reals("joint_external_torque", 156, "external torque", "N·m"),
    _vector("tcp_position", 180, "TCP position X, Y, Z (base frame)", "mm", _XYZ),
    _vector("tcp_orientation", 192, "TCP orientation A, B, C (base frame, Euler Z-Y-Z)",
            "degree", _ABC),
    _vector("tcp_velocity", 204, "TCP velocity X, Y, Z (base frame)", "mm/s", _XYZ),
    _vector("tcp_angular_velocity", 216, "TCP angular velocity RX, RY, RZ (base frame)",
            "degree/s", ("RX", "RY", "RZ")),
    _vector("tool_offset_position", 228, "Tool offset length X, Y, Z (tool frame)", "mm", _XYZ),
    _vector("tool_offset_orientation", 240, "Tool offset angle A, B, C (tool frame)", "degree",
            _ABC),
    _vector("external_force", 252, "External force X, Y, Z (base frame)", "N", _XYZ),
    _vector("external_moment", 264, "External moment X, Y, Z (base frame)", "N·m", _XYZ),
    # The table's "32-64" means registers 32–63: two DWORDs, register 0 in bit 0 of byte 276.
    Field("bit_output_registers", _T2O, 276, CipType.BOOL, 64, "Bit output registers 0–63",
          "Bit Registers", first_bit=0, channels=numbered("Register", 0, 64)),
)
# fmt: on

# fmt: off
O2T_FIELDS: Final[tuple[Field, ...]] = (
    Field("controlbox_do", _O2T, 0, CipType.BOOL, 16, "ControlBox digital outputs 1–16 (command)",
          "I/O", first_bit=0, channels=numbered("DO", 1, 16)),
    # Spec note A: tool DO at bits 16–21 and the AO type at bits 24–25 of word 0.
    Field("tool_do", _O2T, 0, CipType.BOOL, 6, "Tool digital outputs 1–6 (command)", "I/O",
          first_bit=16, channels=numbered("Tool DO", 1, 6)),
    Field("analog_output_type", _O2T, 0, CipType.BOOL, 2, "Analog output type: Out0, Out1",
          "I/O", first_bit=24, channels=numbered("AO", 0, 2), value_names=_ANALOG_TYPE_CODING),
    Field("analog_output", _O2T, 4, CipType.REAL, 2, "Analog outputs 0–1 (command)", "I/O",
          "mA or V per its type", channels=numbered("AO", 0, 2)),
    Field("bit_input_registers", _O2T, 12, CipType.BOOL, 64, "Bit input registers 0–63",
          "Bit Registers", first_bit=0, channels=numbered("Register", 0, 64)),
)
# fmt: on

T2O_ASSEMBLY: Final = Assembly(
    "robot_to_plc",
    _T2O,
    284,
    100,
    "Robot (target) → PLC (originator): I/O, robot state, joint and TCP monitoring, registers",
    T2O_FIELDS,
)
O2T_ASSEMBLY: Final = Assembly(
    "plc_to_robot",
    _O2T,
    20,
    150,
    "PLC (originator) → robot (target): digital, tool and analog outputs, bit input registers",
    O2T_FIELDS,
)
ASSEMBLIES: Final = (T2O_ASSEMBLY, O2T_ASSEMBLY)
FRAME_ECHOED: Final = frozenset(f.name for f in O2T_FIELDS) & {f.name for f in T2O_FIELDS}
"""O→T fields the robot reports back in its T→O frame (actual outputs): a write of one is
confirmed by a frame. The rest (bit input registers) is confirmed when the O→T packet carrying
it has gone out."""


@dataclass(frozen=True, slots=True)
class ConnectionPoints:
    """The robot's default connection points (assembly instances) for class 1 connections.

    Exclusive owner: configuration → O→T → T→O; input-only sends its O→T to the heartbeat
    point, listen-only to its own (docs/protocol.md, "Connection types"). Every one is a
    setting on both sides, in case a controller version numbers them otherwise.
    """

    configuration: int = 151
    o2t: int = O2T_ASSEMBLY.default_instance
    t2o: int = T2O_ASSEMBLY.default_instance
    input_only: int = 198
    listen_only: int = 199


CONNECTION_POINTS: Final = ConnectionPoints()

ANALOG_OUTPUT_RANGES: Final = {"current": (4.0, 20.0, "mA"), "voltage": (0.0, 10.0, "V")}
"""Valid setpoint range (low, high, unit) of an analog output for each type coding."""

_WHITE = ("white",)

# fmt: off
ROBOT_STATES: Final[tuple[RobotStateInfo, ...]] = (
    RobotStateInfo(0, "EMERGENCY_STOP", "The emergency stop state.", ("red",),
                   label="Emergency stop"),
    RobotStateInfo(1, "INITIALIZING",
                   "The initialization state for setting various parameters.", ("blue",),
                   label="Initializing"),
    RobotStateInfo(2, "SAFE_OFF", "The servo off state. This is robot stop state due to a "
                   "function error or operation error.", ("red",),
                   label="Safe off (servo off)"),
    RobotStateInfo(3, "INTERRUPTED", "The system is in a protective stop state due to protective "
                   "stop input, exceeding the safety threshold, etc.", ("yellow",),
                   label="Protective stop"),
    RobotStateInfo(4, "MANUAL_STANDBY", "This is the default status of teaching.", ("blue",),
                   label="Manual standby"),
    RobotStateInfo(5, "MANUAL_JOGGING", "The jog function is used to operate the robot.",
                   ("blue",),
                   label="Manual jogging"),
    RobotStateInfo(6, "MANUAL_HANDGUIDING",
                   "The robot can be operated manually during teaching.", ("blue",),
                   label="Manual hand-guiding"),
    RobotStateInfo(7, "RECOVERY_STANDBY", "Recovery in progress. All safety functions except for "
                   "axis and TCP speed monitoring are disabled during recovery.", ("yellow",),
                   label="Recovery standby"),
    RobotStateInfo(8, "RECOVERY_JOGGING", "The jogs of each axis can be used to correct the "
                   "exceeded safety threshold.", ("yellow",),
                   label="Recovery jogging"),
    RobotStateInfo(9, "BACKDRIVE_HOLD", "All brakes of 6 joints are engaged, and Backdrive "
                   "motion is locked.", ("yellow",),
                   label="Backdrive hold"),
    RobotStateInfo(10, "BACKDRIVE_RELEASE", "Brake of one or more joint(s) is released due to "
                   "the selection of brake release.", ("yellow",),
                   label="Backdrive release"),
    RobotStateInfo(11, "BACKDRIVE_RELEASE_BY_COCKPIT", "Brake of one or more joint(s) is "
                   "released due to the Cockpit.", ("yellow",),
                   label="Backdrive release by Cockpit"),
    RobotStateInfo(12, "RECOVERY_HANDGUIDING", "The robot can be moved directly by hand to "
                   "correct the exceeded safety threshold.", ("yellow",),
                   label="Recovery hand-guiding"),
    RobotStateInfo(13, "STANDALONE_STANDBY", "The Teach Pendant UI is in the actual mode "
                   "execution screen in a single work space. White is displayed for a Standalone "
                   "Zone.", _WHITE, colour_from_table=True,
                   label="Standalone standby"),
    RobotStateInfo(14, "STANDALONE_RUNNING", "The task program is being executed. White is "
                   "displayed for a Standalone Zone.", _WHITE, colour_from_table=True,
                   label="Standalone running"),
    RobotStateInfo(15, "COLLABORATIVE_STANDBY", "The Teach Pendant UI is in the actual mode "
                   "execution screen in a single work space. Green is displayed for a "
                   "Collaborative Zone.", ("green",), colour_from_table=True,
                   label="Collaborative standby"),
    RobotStateInfo(16, "COLLABORATIVE_RUNNING", "The task program is being executed. Green is "
                   "displayed for a Collaborative Zone.", ("green",), colour_from_table=True,
                   label="Collaborative running"),
    RobotStateInfo(17, "HIGH_PRIORITY_RUNNING", "The task program is being executed. White and "
                   "Yellow are displayed by turns for a High Priority Zone.", ("white", "yellow"),
                   colour_from_table=True,
                   label="High-priority running"),
    RobotStateInfo(18, "AUTO_MEASURE", "The weight and center of gravity point of the end "
                   "effector are measured automatically.", _WHITE,
                   label="Automatic measuring"),
    RobotStateInfo(19, "HANDGUIDING_CONTROL_STANDBY", "The Handguiding command is executed "
                   "during task program execution.", _WHITE,
                   label="Hand-guiding control standby"),
    RobotStateInfo(20, "HANDGUIDING_CONTROL_RUNNING", "The robot pose can be changed by pressing "
                   "the \"Handguiding\" button.", _WHITE,
                   label="Hand-guiding control running"),
)
# fmt: on

UNKNOWN_STATE_NAME: Final = "UNKNOWN"
"""Name of a robot-state value outside the table: shown as such, never an error."""


def robot_state_name(value: int) -> str:
    """The enum name of a robot-state value, or ``UNKNOWN``."""
    return _STATE_NAMES.get(value, UNKNOWN_STATE_NAME)


_STATE_NAMES: Final = {state.value: state.name for state in ROBOT_STATES}


def flag_fields() -> tuple[Field, ...]:
    """The five status flags, in the table's order."""
    return tuple(f for f in T2O_FIELDS if f.flag is not None)


def field_by_name(direction: Direction, name: str) -> Field:
    """Look a field up by its canonical name; ``KeyError`` if there is none."""
    assembly = T2O_ASSEMBLY if direction is Direction.T_TO_O else O2T_ASSEMBLY
    for f in assembly.fields:
        if f.name == name:
            return f
    raise KeyError(name)


def used_bit_mask(assembly: Assembly) -> bytes:
    """A mask with every bit that some field of ``assembly`` covers set; the rest is reserved."""
    mask = bytearray(assembly.size_bytes)
    for f in assembly.fields:
        for bit in range(f.first_wire_bit, f.first_wire_bit + f.bit_count):
            mask[bit // 8] |= 1 << (bit % 8)
    return bytes(mask)
