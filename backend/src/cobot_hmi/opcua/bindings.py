"""Layer: service (OPC UA). Where each variable's value comes from: the builders' output, the
updater's input.

A ``Binding`` ties one variable to a function of the newest frame (or of the command image
the service sends); ``RobotNodes`` holds every binding of one robot and the few nodes that
change with something else than a frame (its identity, its analog channels' types, its status).
Pure data: imports only asyncua's types and the codec's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from asyncua import ua

from cobot_hmi.codec import CommandImage, Frame


@dataclass(frozen=True, slots=True)
class Binding:
    """One variable whose value is ``read(frame)`` (or ``read(image)``), of ``variant``."""

    node: ua.NodeId
    read: Callable[[Frame], object]
    variant: ua.VariantType
    field_position: int | None = None
    """The one frame field ``read`` reads (its position in ``Frame``), so the updater reads it
    again only when that field changed; ``None``: ``read`` may read any field, every frame."""


@dataclass(frozen=True, slots=True)
class CommandBinding:
    """One variable of the command image: ``field`` and channel ``index`` (``None``: scalar)."""

    node: ua.NodeId
    read: Callable[[CommandImage], object]
    variant: ua.VariantType
    field: str
    index: int | None


@dataclass(frozen=True, slots=True)
class AnalogUnit:
    """An analog channel whose engineering unit and range follow its type channel."""

    units: ua.NodeId
    """The ``EngineeringUnits`` property."""
    range: ua.NodeId
    """The ``EURange`` property."""
    type_name: Callable[[object], str]
    """The channel's type name (``current``, ``voltage``) from the frame or the image."""
    from_command: bool


@dataclass(frozen=True, slots=True)
class JointRange:
    """A joint's ``EURange`` property: the arm's position or speed limit of joint ``joint``."""

    node: ua.NodeId
    joint: int
    speed: bool


@dataclass(frozen=True, slots=True)
class MachineState:
    """A state of a finite state machine of the companion models: its name and its node."""

    name: str
    node: ua.NodeId


@dataclass(frozen=True, slots=True)
class StateMachineBinding:
    """A state machine whose ``CurrentState`` (and its ``Id``) is ``read(frame)``, or
    ``read(None)`` while there is no frame (the link down, none yet)."""

    current_state: ua.NodeId
    state_id: ua.NodeId
    read: Callable[[Frame | None], MachineState]


@dataclass(frozen=True, slots=True)
class HealthJoint:
    """One joint's health variables (``health_nodes``): its verdict, its reason, and its
    reducer's life used (a Machinery lifetime counter, %)."""

    joint: int
    """1-based, as the robot labels its joints."""
    verdict: ua.NodeId
    reason: ua.NodeId
    life_used: ua.NodeId


@dataclass
class RobotNodes:
    """Every node of one robot that the updater writes (see the module docstring)."""

    robot: str
    namespace: int
    frame: list[Binding] = field(default_factory=list)
    command: list[CommandBinding] = field(default_factory=list)
    analog_units: list[AnalogUnit] = field(default_factory=list)
    joint_ranges: list[JointRange] = field(default_factory=list)
    models: list[ua.NodeId] = field(default_factory=list)
    """``Model`` properties: the identity's product name."""
    serial_numbers: list[ua.NodeId] = field(default_factory=list)
    product_codes: list[ua.NodeId] = field(default_factory=list)
    software_revisions: list[ua.NodeId] = field(default_factory=list)
    """``SoftwareRevision`` properties: the frame's controller version."""
    product_instance_uris: list[ua.NodeId] = field(default_factory=list)
    """``ProductInstanceUri`` properties (Machinery): made of the identity."""
    state_machines: list[StateMachineBinding] = field(default_factory=list)
    connection_state: ua.NodeId | None = None
    control_holder: ua.NodeId | None = None
    take_control: ua.NodeId | None = None
    release_control: ua.NodeId | None = None
    health_verdict: ua.NodeId | None = None
    """The robot's health verdict (its worst joint's)."""
    health_joints: list[HealthJoint] = field(default_factory=list)
    constants: list[tuple[ua.NodeId, ua.Variant]] = field(default_factory=list)
    """Values that never change (nameplates, engineering units), written once."""
    unsupported: list[ua.NodeId] = field(default_factory=list)
    """Mandatory members the implicit I/O does not carry: Null, ``BadNotSupported``."""

    @property
    def command_by_node(self) -> dict[ua.NodeId, CommandBinding]:
        return {binding.node: binding for binding in self.command}
