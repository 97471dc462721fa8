"""Layer: service (OPC UA). The whole I/O layout of a robot as variables in its own namespace.

Generated from ``cobot_hmi.layout``, the one place names, units, channels and enums are
written: an object per field under ``Frame`` (the 284-byte T→O frame) and ``Command`` (the
20-byte O→T image), a variable per channel named by the channel's label (``DO 1``,
``Register 63``, ``J3``), its NodeId the API's key (``<robot>.Frame.controlbox_do.0``;
scalars ``<robot>.Frame.robot_state``, a record's elements ``….controller_version.major``).

Types: a bit is a ``Boolean``; a coded bit (analog type: current, voltage) a
``MultiStateDiscreteType`` with its ``EnumStrings``; a REAL a ``Float`` of ``AnalogUnitType``
with its ``EngineeringUnits`` (an analog channel's unit and ``EURange`` follow its type); the
robot state a ``MultiStateValueDiscreteType`` with the state enum's ``EnumValues`` and its
``ValueAsText``; a USINT a ``Byte``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Final

from asyncua import ua

from cobot_hmi.codec import CommandImage, Frame
from cobot_hmi.layout import (
    O2T_FIELDS,
    ROBOT_STATES,
    T2O_FIELDS,
    UNKNOWN_STATE_NAME,
    CipType,
    Field,
)
from cobot_hmi.opcua.bindings import AnalogUnit, Binding, CommandBinding, RobotNodes
from cobot_hmi.opcua.nodes import READ, READ_WRITE, NodeBuilder
from cobot_hmi.opcua.units import PER_TYPE, analog_unit, unit_for

_ANALOG_UNIT_TYPE: Final = ua.NodeId(ua.ObjectIds.AnalogUnitType)
_MULTI_STATE_DISCRETE: Final = ua.NodeId(ua.ObjectIds.MultiStateDiscreteType)
_MULTI_STATE_VALUE_DISCRETE: Final = ua.NodeId(ua.ObjectIds.MultiStateValueDiscreteType)
_FLOAT: Final = ua.NodeId(ua.ObjectIds.Float)
_BOOLEAN: Final = ua.NodeId(ua.ObjectIds.Boolean)
_BYTE: Final = ua.NodeId(ua.ObjectIds.Byte)
_UINT32: Final = ua.NodeId(ua.ObjectIds.UInt32)
_FRAME_FIELDS: Final = Frame._fields
_COMMAND_FIELDS: Final = CommandImage._fields
_ROBOT_STATE: Final = _FRAME_FIELDS.index("robot_state")
STATE_TEXTS: Final = {state.value: state.name for state in ROBOT_STATES}


def state_text(value: int) -> str:
    return STATE_TEXTS.get(value, UNKNOWN_STATE_NAME)


def _element(position: int, index: int | None) -> Callable[[tuple[object, ...]], object]:
    if index is None:
        return lambda record: record[position]

    def read(record: tuple[object, ...]) -> object:
        values = record[position]
        assert isinstance(values, tuple)
        return values[index]

    return read


def _type_name(field: Field, index: int, fields: tuple[str, ...]) -> Callable[[object], str]:
    """The type name (``current``/``voltage``) of channel ``index`` of ``field``'s type field."""
    type_field = next(f for f in (T2O_FIELDS + O2T_FIELDS) if f.name == f"{field.name}_type")
    position = fields.index(type_field.name)
    names = type_field.value_names

    def read(record: object) -> str:
        assert isinstance(record, tuple)
        code = record[position][index]
        return names[code] if 0 <= code < len(names) else names[0]

    return read


class LayoutBuilder:
    """Adds one robot's ``Frame`` and ``Command`` objects and records their bindings."""

    def __init__(self, builder: NodeBuilder, nodes: RobotNodes, *, writable: bool) -> None:
        self._builder = builder
        self._nodes = nodes
        self._ns = nodes.namespace
        self._writable = writable

    def _name(self, text: str) -> ua.QualifiedName:
        return ua.QualifiedName(text, self._ns)

    def add(self, robot_object: ua.NodeId) -> None:
        robot = self._nodes.robot
        frame = self._builder.add_object(
            robot_object,
            ua.NodeId(f"{robot}.Frame", self._ns),
            self._name("Frame"),
            description="The robot's T→O frame (284 bytes), every field: what the robot reports",
        )
        for field in T2O_FIELDS:
            self._field(frame, field, command=False)
        command = self._builder.add_object(
            robot_object,
            ua.NodeId(f"{robot}.Command", self._ns),
            self._name("Command"),
            description="The O→T command image (20 bytes) the service sends to the robot",
        )
        for field in O2T_FIELDS:
            self._field(command, field, command=True)

    def _field(self, parent: ua.NodeId, field: Field, *, command: bool) -> None:
        fields = _COMMAND_FIELDS if command else _FRAME_FIELDS
        position = fields.index(field.name)
        base = f"{parent.Identifier}.{field.name}"
        if field.scalar:
            self._variable(
                parent,
                base,
                field.name,
                field=field,
                position=position,
                index=None,
                command=command,
            )
            return
        holder = self._builder.add_object(
            parent, ua.NodeId(base, self._ns), self._name(field.name), description=field.description
        )
        labels = field.element_names or field.channels or tuple(str(i) for i in range(field.count))
        for index, label in enumerate(labels):
            key = label if field.element_names else str(index)
            self._variable(
                holder,
                f"{base}.{key}",
                label,
                field=field,
                position=position,
                index=index,
                command=command,
            )

    def _variable(
        self,
        parent: ua.NodeId,
        nodeid_text: str,
        name: str,
        *,
        field: Field,
        position: int,
        index: int | None,
        command: bool,
    ) -> None:
        nodeid = ua.NodeId(nodeid_text, self._ns)
        builder = self._builder
        access = READ_WRITE if command and self._writable else READ
        description = field.description if index is None else f"{field.description}: {name}"
        if field.enum is not None:
            variant, data_type, type_definition = (
                ua.VariantType.Byte,
                _BYTE,
                _MULTI_STATE_VALUE_DISCRETE,
            )
        elif field.value_names:
            variant, data_type, type_definition = (
                ua.VariantType.UInt32,
                _UINT32,
                _MULTI_STATE_DISCRETE,
            )
        elif field.cip_type is CipType.BOOL:
            variant, data_type = ua.VariantType.Boolean, _BOOLEAN
            type_definition = ua.NodeId(ua.ObjectIds.BaseDataVariableType)
        elif field.cip_type is CipType.REAL:
            variant, data_type, type_definition = ua.VariantType.Float, _FLOAT, _ANALOG_UNIT_TYPE
        else:
            variant, data_type = ua.VariantType.Byte, _BYTE
            type_definition = ua.NodeId(ua.ObjectIds.BaseDataVariableType)
        builder.add_variable(
            parent,
            nodeid,
            self._name(name),
            ua.Variant(),
            data_type,
            type_definition=type_definition,
            access=access,
            description=description,
        )
        self._properties(nodeid, field, index, command=command)
        read = _element(position, index)
        if command:
            self._nodes.command.append(CommandBinding(nodeid, read, variant, field.name, index))
        else:
            self._nodes.frame.append(Binding(nodeid, read, variant, position))
        if field.enum is not None:
            text = ua.NodeId(f"{nodeid_text}.ValueAsText", self._ns)
            self._nodes.frame.append(
                Binding(
                    text,
                    lambda frame: ua.LocalizedText(state_text(frame.robot_state)),
                    ua.VariantType.LocalizedText,
                    _ROBOT_STATE,  # read again only when the state changed (``FieldReads``)
                )
            )

    def _properties(
        self, nodeid: ua.NodeId, field: Field, index: int | None, *, command: bool
    ) -> None:
        builder = self._builder
        if field.enum is not None:
            values = [
                ua.EnumValueType(
                    Value=state.value,
                    DisplayName=ua.LocalizedText(state.name),
                    Description=ua.LocalizedText(state.label),
                )
                for state in ROBOT_STATES
            ]
            builder.add_property(
                nodeid,
                ua.QualifiedName("EnumValues", 0),
                ua.Variant(values, ua.VariantType.ExtensionObject),
                ua.NodeId(ua.ObjectIds.EnumValueType),
                value_rank=ua.ValueRank.OneDimension,
            )
            builder.add_property(
                nodeid,
                ua.QualifiedName("ValueAsText", 0),
                ua.Variant(),
                ua.NodeId(ua.ObjectIds.LocalizedText),
            )
        elif field.value_names:
            builder.add_property(
                nodeid,
                ua.QualifiedName("EnumStrings", 0),
                ua.Variant(
                    [ua.LocalizedText(n) for n in field.value_names], ua.VariantType.LocalizedText
                ),
                ua.NodeId(ua.ObjectIds.LocalizedText),
                value_rank=ua.ValueRank.OneDimension,
            )
        elif field.cip_type is CipType.REAL:
            per_type = field.unit == PER_TYPE
            if per_type:
                unit, eu_range = analog_unit("current")
            else:
                unit, eu_range = unit_for(field.unit), None
            units = builder.add_property(
                nodeid,
                ua.QualifiedName("EngineeringUnits", 0),
                ua.Variant(unit.information(), ua.VariantType.ExtensionObject),
                ua.NodeId(ua.ObjectIds.EUInformation),
            )
            if per_type and eu_range is not None and index is not None:
                fields = _COMMAND_FIELDS if command else _FRAME_FIELDS
                range_node = builder.add_property(
                    nodeid,
                    ua.QualifiedName("EURange", 0),
                    ua.Variant(eu_range, ua.VariantType.ExtensionObject),
                    ua.NodeId(ua.ObjectIds.Range),
                )
                self._nodes.analog_units.append(
                    AnalogUnit(units, range_node, _type_name(field, index, fields), command)
                )
