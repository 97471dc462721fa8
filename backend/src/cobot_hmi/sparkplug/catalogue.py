"""Layer: service (Sparkplug). Pure: the metrics of a robot (device) and of the node, derived
from the layout (``cobot_hmi.layout``), the one place fields, units and enums are written.

One metric per element: ``joint_position/J1``, ``controlbox_di/DI 1``, ``controller_version/
major``; scalars by the field's name (``robot_state``, ``servo_on``). Types: ``BOOL`` bits are
``Boolean``, ``REAL`` is ``Float``, ``USINT`` and coded fields (the analog types, the robot state)
are ``UInt8`` with their names in a ``name`` property. Births carry ``engUnit`` (the layout's
unit), ``description`` and, for analog values, ``deadband``. The robot's O→T image follows as
``command/<field>/<channel>`` (writable by DCMD when MQTT writes are on), then the control and
write-outcome metrics.

Aliases are unique across the node (Sparkplug 3.0 requires it): robot ``n`` (1-based, in the
settings' order) has ``n * ALIAS_STRIDE + offset``; node metrics have none.

Imports only the layout and ``payload``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from typing import Final

from cobot_hmi.layout import O2T_FIELDS, T2O_FIELDS, CipType, Field, robot_state_name
from cobot_hmi.sparkplug.payload import DataType

ALIAS_STRIDE: Final = 1000
BD_SEQ: Final = "bdSeq"
REBIRTH: Final = "Node Control/Rebirth"
ALARM_HISTORY_SINCE: Final = "Node Control/Alarm History Since"
"""With a rebirth request: the alarm transitions since then again (``commands``)."""
CONTROL_HOLDER: Final = "Control/Holder"
CONTROL_TAKE: Final = "Control/Take"
CONTROL_RELEASE: Final = "Control/Release"
WRITE_OUTCOME: Final = "Write/Outcome"
WRITE_REASON: Final = "Write/Reason"
COMMAND_PREFIX: Final = "command/"


class Role(Enum):
    DISCRETE = "discrete"
    """Bits, coded values, the robot state, the version: every change is sent."""
    ANALOG = "analog"
    """REAL values: sent when they move by the deadband or more."""
    COMMAND = "command"
    """An element of the O→T image (DCMD-writable)."""
    STATUS = "status"
    """Control and write-outcome metrics of the edge node itself."""
    EVENT = "event"
    """From the service's events: alarms, cycle times, health (``event_metrics``)."""


@dataclass(frozen=True, slots=True)
class MetricDef:
    name: str
    offset: int
    """Index in the device's metric list; the alias is ``robot base + offset``."""
    datatype: DataType
    role: Role
    field: str | None = None
    index: int | None = None
    """Element index in the field; ``None`` for a scalar field."""
    unit: str = ""
    description: str = ""
    deadband: float = 0.0
    value_names: tuple[str, ...] = ()
    writable: bool = False


def _datatype(f: Field) -> DataType:
    if f.cip_type is CipType.REAL:
        return DataType.FLOAT
    if f.value_kind == "bool":
        return DataType.BOOLEAN
    return DataType.UINT8


def _element_names(f: Field) -> tuple[str, ...]:
    return f.element_names or f.channels or tuple(str(i) for i in range(f.count))


@dataclass(frozen=True, slots=True)
class FieldSpan:
    """A T→O field and where its elements sit in the device's metric list."""

    field: str
    first: int
    count: int
    scalar: bool


class _MetricList:
    """The catalogue's metrics as they are added, each at the next offset, and the spans of
    the T→O fields among them."""

    def __init__(self) -> None:
        self.metrics: list[MetricDef] = []
        self.discrete: list[FieldSpan] = []
        self.analog: list[FieldSpan] = []

    def add(self, **kwargs: object) -> MetricDef:
        metric = MetricDef(offset=len(self.metrics), **kwargs)  # type: ignore[arg-type]
        self.metrics.append(metric)
        return metric

    def add_frame_fields(self, deadbands: Mapping[str, float]) -> None:
        """Every T→O field's elements, a span each (discrete or analog)."""
        for f in T2O_FIELDS:
            role = Role.ANALOG if f.cip_type is CipType.REAL else Role.DISCRETE
            deadband = 0.0
            if role is Role.ANALOG:
                deadband = float(deadbands.get(f.name, deadbands.get(f.unit, 0.0)))
            span = FieldSpan(f.name, len(self.metrics), 1 if f.scalar else f.count, f.scalar)
            (self.analog if role is Role.ANALOG else self.discrete).append(span)
            names = (f.name,) if f.scalar else tuple(f"{f.name}/{e}" for e in _element_names(f))
            for index, name in enumerate(names):
                self.add(
                    name=name,
                    datatype=_datatype(f),
                    role=role,
                    field=f.name,
                    index=None if f.scalar else index,
                    unit=f.unit,
                    description=f.description,
                    deadband=deadband,
                    value_names=f.value_names,
                )

    def add_command_fields(self) -> None:
        """Every O→T element, writable, under ``COMMAND_PREFIX``."""
        for f in O2T_FIELDS:
            for index, element in enumerate(_element_names(f)):
                self.add(
                    name=f"{COMMAND_PREFIX}{f.name}/{element}",
                    datatype=_datatype(f),
                    role=Role.COMMAND,
                    field=f.name,
                    index=index,
                    unit=f.unit,
                    description=f.description,
                    value_names=f.value_names,
                    writable=True,
                )

    def add_status(
        self, name: str, datatype: DataType, description: str, *, writable: bool = False
    ) -> MetricDef:
        return self.add(
            name=name,
            datatype=datatype,
            role=Role.STATUS,
            description=description,
            writable=writable,
        )


class Catalogue:
    """Every metric of one robot, in a fixed order (see the module docstring)."""

    def __init__(self, deadbands: Mapping[str, float]) -> None:
        """``deadbands``: by T→O field name or by unit (a field's name wins)."""
        made = _MetricList()
        made.add_frame_fields(deadbands)
        made.add_command_fields()
        self.control_holder = made.add_status(
            CONTROL_HOLDER,
            DataType.STRING,
            "who holds control of the robot's outputs (empty: nobody)",
        )
        self.control_take = made.add_status(
            CONTROL_TAKE, DataType.BOOLEAN, "DCMD true: take control for MQTT writes", writable=True
        )
        self.control_release = made.add_status(
            CONTROL_RELEASE, DataType.BOOLEAN, "DCMD true: release control", writable=True
        )
        self.write_outcome = made.add_status(
            WRITE_OUTCOME,
            DataType.STRING,
            "outcome of the last DCMD (confirmed, refused, invalid, timeout, …)",
        )
        self.write_reason = made.add_status(
            WRITE_REASON, DataType.STRING, "why, when the last DCMD was not confirmed"
        )
        metrics = made.metrics
        assert len(metrics) < ALIAS_STRIDE
        self.metrics: tuple[MetricDef, ...] = tuple(metrics)
        self.discrete_spans: tuple[FieldSpan, ...] = tuple(made.discrete)
        self.analog_spans: tuple[FieldSpan, ...] = tuple(made.analog)
        self.command_metrics: tuple[MetricDef, ...] = tuple(
            m for m in metrics if m.role is Role.COMMAND
        )
        self.by_name: dict[str, MetricDef] = {m.name: m for m in metrics}

    def analog_deadbands(self) -> list[float]:
        """Deadbands of the analog metrics, in the order the analog spans flatten to."""
        return [
            m.deadband
            for span in self.analog_spans
            for m in self.metrics[span.first : span.first + span.count]
        ]


def has_state_names(metric: MetricDef) -> bool:
    """Whether ``state_name`` may name a value of ``metric`` (then its DATA carries a ``name``
    property with it)."""
    return metric.field == "robot_state" or bool(metric.value_names)


def state_name(metric: MetricDef, value: object) -> str | None:
    """The name a coded metric's value has (robot state, analog type), else ``None``."""
    if metric.field == "robot_state" and isinstance(value, int):
        return robot_state_name(value)
    if metric.value_names and isinstance(value, int) and 0 <= value < len(metric.value_names):
        return metric.value_names[value]
    return None
