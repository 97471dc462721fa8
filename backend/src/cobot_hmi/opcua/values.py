"""Layer: service (OPC UA). The variables follow the robot: one update per monitoring period.

``RobotValues.update`` takes one robot's ``Sample`` (the newest frame of the period, the link,
the command image, the control holder, the identity: ``feed``) and writes, on the server's
loop, only what changed since the last period: OPC UA's SourceTimestamp is the time of a
value's last change (Part 4 §7.7.3), here the frame's kernel receive time. A subscription
therefore gets a notification per change, at most one per variable per period.

While the robot's link is down every frame-derived variable is Null with
``BadCommunicationError`` (its SourceTimestamp the moment the link went), and Good again with
the first frame after it returns; before the first frame they are ``BadWaitingForInitialData``.
The command image is the service's own (what it sends, or would send): always Good. The
nameplates (identity) and the software revision keep their last value. The Machinery state
machines (``machinery``) stay Good: without a frame the robot is NotAvailable, mode None.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any, Final

from asyncua import Server, ua
from asyncua.server.monitored_item_service import MonitoredItemService

from cobot_hmi.arms import ARMS, Arm
from cobot_hmi.codec import CommandImage, Frame
from cobot_hmi.opcua.bindings import MachineState, RobotNodes
from cobot_hmi.opcua.machinery import MANUFACTURER_URI
from cobot_hmi.opcua.units import analog_unit

_VALUE: Final = ua.AttributeIds.Value
GOOD: Final = ua.StatusCode(ua.StatusCodes.Good)
COMMUNICATION_ERROR: Final = ua.StatusCode(ua.StatusCodes.BadCommunicationError)
WAITING: Final = ua.StatusCode(ua.StatusCodes.BadWaitingForInitialData)
NOT_SUPPORTED: Final = ua.StatusCode(ua.StatusCodes.BadNotSupported)
_NULL: Final = ua.Variant()


@dataclass(frozen=True, slots=True)
class Identity:
    """What the robot's CIP identity says, as the nameplates show it."""

    product_name: str
    serial_number: str
    product_code: str

    @property
    def product_instance_uri(self) -> str:
        """Machinery's ProductInstanceUri, globally unique per robot as OPC 40001-1 recommends
        it: the manufacturer's URI, then the product code and the serial number."""
        return f"{MANUFACTURER_URI}/{self.product_code}/{self.serial_number}"

    @property
    def arm(self) -> Arm:
        """The arm its product name names (``M1013`` in "Doosan M1013"), else the first."""
        upper = self.product_name.upper()
        return next((arm for arm in ARMS if arm.name in upper), ARMS[0])


@dataclass(frozen=True, slots=True)
class Sample:
    """One robot at one monitoring tick (``feed.ServiceFeed.sample``)."""

    frame: Frame | None
    """The newest frame of the period; ``None`` when no new one came."""
    received_at: float
    """Its kernel receive time, epoch seconds."""
    connected: bool
    connection_state: str
    command: CommandImage | None
    control_holder: str
    identity: Identity | None
    health: Mapping[str, object] | None = None
    """The robot's latest ``health`` event (``service.health``), if it had one."""


class SharedDataValue(ua.DataValue):
    """A DataValue that asyncua's monitored items may share instead of copying.

    asyncua deep-copies the value at every data change for every monitored item watching it
    (``MonitoredItemValues.set_current_datavalue``: "to prevent referencing the inner value",
    a guard against a writer that changes a stored value in place), which was over half of the
    server thread's time with one client on every variable. ``RobotValues`` makes a new
    DataValue for every change and never changes one it has stored, nor its Variant, nor the
    value inside (numbers, strings and tuples, or asyncua's structures made for the write), so
    a copy would always equal the original: sharing it is exact. It encodes as a DataValue
    (asyncua encodes a field by its declared type)."""

    __slots__ = ()

    def __deepcopy__(self, memo: dict[int, object]) -> SharedDataValue:
        return self


_new = object.__new__


def scalar_variant(value: object, variant: ua.VariantType) -> ua.Variant:
    """``ua.Variant(value, variant)``, made without its ``__post_init__`` when ``value`` is a
    scalar (not None, not a list or tuple): given its type, that only sets the fields set
    here, and ran for every changed value of every tick (a sixth of the server's thread)."""
    if value is None or isinstance(value, list | tuple):
        return ua.Variant(value, variant)
    made: ua.Variant = _new(ua.Variant)
    made.Value = value
    made.VariantType = variant
    made.Dimensions = None
    made.is_array = False
    return made


def shared_value(
    variant: ua.Variant, status: ua.StatusCode, source: datetime, server: datetime
) -> SharedDataValue:
    """``SharedDataValue(variant, StatusCode=status, SourceTimestamp=source,
    ServerTimestamp=server)`` without the dataclass's ``__init__`` and ``__post_init__``
    (``variant`` is a Variant already): the same fields."""
    value: SharedDataValue = _new(SharedDataValue)
    value.Encoding = 0
    value.Value = variant
    value.StatusCode = status
    value.SourceTimestamp = source
    value.ServerTimestamp = server
    value.SourcePicoseconds = None
    value.ServerPicoseconds = None
    return value


_ASYNCUA_DATACHANGE: Final = MonitoredItemService.datachange_callback
_DISABLED: Final = ua.MonitoringMode.Disabled
_STATUS_VALUE: Final = ua.DataChangeTrigger.StatusValue


async def notify(service: MonitoredItemService, handle: int, value: SharedDataValue) -> None:
    """asyncua's ``MonitoredItemService.datachange_callback`` for one of these values: the same
    checks (the item's mode, its filter or a change of status or value) and the same queue,
    without what cost most of it for values that never change once stored: a notification
    made, with a default DataValue and Variant of its own, before knowing it goes out (now
    made only when it does, with this value), and the deep copy that ``SharedDataValue``
    answers with itself (the previous value kept as asyncua keeps it)."""
    mid = service._monitored_datachange[handle]
    item = service._monitored_items[mid]
    if item.mode == _DISABLED:
        return
    values = item.mvalue
    values.old_dvalue = values.current_dvalue
    values.current_dvalue = value
    flt = item.filter
    if flt:
        changed = service._is_data_changed(values, flt.Trigger)
        changed = changed and service._is_deadband_exceeded(values, flt)
    else:
        changed = service._is_data_changed(values, _STATUS_VALUE)
    if changed:
        event: ua.MonitoredItemNotification = _new(ua.MonitoredItemNotification)
        event.ClientHandle = item.client_handle
        event.Value = value
        await service.isub.enqueue_datachange_event(mid, event, item.queue_size)


def _utc(epoch_s: float) -> datetime:
    return datetime.fromtimestamp(epoch_s, UTC)


class RobotValues:
    """The values of one robot's variables as last written (see the module docstring)."""

    def __init__(self, server: Server, nodes: RobotNodes) -> None:
        self._aspace = server.iserver.aspace
        self.nodes = nodes
        self._frame_values: list[object] = [None] * len(nodes.frame)
        self._command_values: list[object] = [None] * len(nodes.command)
        self._machine_states: list[MachineState | None] = [None] * len(nodes.state_machines)
        self._analog_types: list[str | None] = [None] * len(nodes.analog_units)
        self._frame_status: ua.StatusCode | None = None
        self._revision: str | None = None
        self._identity: Identity | None = None
        self._state: str | None = None
        self._holder: str | None = None
        self._health_event: Mapping[str, object] | None = None
        self._health_values: dict[ua.NodeId, object] = {}
        self.writes = 0
        """Values written (a counter: the bench reads it)."""
        self._attributes: dict[ua.NodeId, Any] = {}
        """asyncua's value attribute of each variable written (found once)."""
        self._now = _utc(time.time())
        """The ServerTimestamp of this update's writes."""

    async def _write(
        self, node: ua.NodeId, variant: ua.Variant, status: ua.StatusCode, source: datetime
    ) -> None:
        """One value as asyncua's own ``write_attribute_value`` stores it (the value, then each
        monitored item's callback), without its per-write checks: every variable here is
        written with its own data type, and a Bad status always with a Null value."""
        attribute = self._attributes.get(node)
        if attribute is None:
            attribute = self._attributes[node] = self._aspace[node].attributes[_VALUE]
        value = shared_value(variant, status, source, self._now)
        self.writes += 1
        attribute.value = value
        attribute.value_callback = None
        callbacks = attribute.datachange_callbacks
        if callbacks:
            for handle, callback in list(callbacks.items()):
                if getattr(callback, "__func__", None) is _ASYNCUA_DATACHANGE:
                    await notify(callback.__self__, handle, value)
                else:
                    await callback(handle, value)

    async def start(self) -> None:
        """The values that never change, the unsupported members, and no data yet."""
        now = self._now = _utc(time.time())
        for node, variant in self.nodes.constants:
            await self._write(node, variant, GOOD, now)
        for node in self.nodes.unsupported:
            await self._write(node, _NULL, NOT_SUPPORTED, now)
        nodes = self.nodes
        identity = (nodes.models, nodes.serial_numbers, nodes.product_codes)
        for node in (node for group in identity for node in group):
            await self._write(node, _NULL, WAITING, now)
        for node in nodes.product_instance_uris:
            await self._write(node, _NULL, WAITING, now)
        await self._frames_status(WAITING, now)
        await self._state_machines(None, now)
        for node in self._health_nodes():
            await self._write(node, _NULL, WAITING, now)

    async def update(self, sample: Sample) -> None:
        now = time.time()
        self._now = _utc(now)
        if sample.connection_state != self._state and self.nodes.connection_state is not None:
            self._state = sample.connection_state
            text = ua.Variant(sample.connection_state, ua.VariantType.String)
            await self._write(self.nodes.connection_state, text, GOOD, _utc(now))
        if sample.control_holder != self._holder and self.nodes.control_holder is not None:
            self._holder = sample.control_holder
            holder = ua.Variant(sample.control_holder, ua.VariantType.String)
            await self._write(self.nodes.control_holder, holder, GOOD, _utc(now))
        if sample.identity is not None and sample.identity != self._identity:
            await self._nameplates(sample.identity, _utc(now))
        if sample.command is not None:
            await self._command(sample.command, _utc(now))
        if sample.health is not None and sample.health is not self._health_event:
            self._health_event = sample.health
            await self._health(sample.health)
        if not sample.connected:
            if self._frame_status is GOOD:
                await self._frames_status(COMMUNICATION_ERROR, _utc(now))
            await self._state_machines(None, _utc(now))
            return
        if sample.frame is not None:
            await self._frame(sample.frame, _utc(sample.received_at))
            await self._state_machines(sample.frame, _utc(sample.received_at))

    def _health_nodes(self) -> list[ua.NodeId]:
        nodes = self.nodes
        joints = [n for j in nodes.health_joints for n in (j.verdict, j.reason, j.life_used)]
        return ([nodes.health_verdict] if nodes.health_verdict is not None else []) + joints

    async def _health(self, event: Mapping[str, object]) -> None:
        """A new ``health`` event: each of its values that changed, at the event's time."""
        when = event.get("time")
        source = _utc(float(when)) if isinstance(when, int | float) else self._now
        values: list[tuple[ua.NodeId | None, object, ua.VariantType]] = [
            (self.nodes.health_verdict, event.get("verdict"), ua.VariantType.String)
        ]
        joints = event.get("joints")
        by_joint = {
            entry.get("joint"): entry
            for entry in (joints if isinstance(joints, list | tuple) else [])
            if isinstance(entry, Mapping)
        }
        for joint in self.nodes.health_joints:
            entry = by_joint.get(joint.joint, {})
            life = entry.get("life_used_percent")
            values += [
                (joint.verdict, entry.get("verdict"), ua.VariantType.String),
                (joint.reason, entry.get("reason"), ua.VariantType.String),
                (
                    joint.life_used,
                    float(life) if isinstance(life, int | float) else None,
                    ua.VariantType.Double,
                ),
            ]
        for node, value, variant in values:
            if node is None or value is None or self._health_values.get(node) == value:
                continue
            self._health_values[node] = value
            await self._write(node, ua.Variant(value, variant), GOOD, source)

    async def _frames_status(self, status: ua.StatusCode, source: datetime) -> None:
        """Every frame-derived variable Null with ``status`` (the link down, no data yet)."""
        self._frame_status = status
        for index, binding in enumerate(self.nodes.frame):
            self._frame_values[index] = None
            await self._write(binding.node, _NULL, status, source)

    async def _frame(self, frame: Frame, source: datetime) -> None:
        force = self._frame_status is not GOOD
        self._frame_status = GOOD
        values = self._frame_values
        for index, binding in enumerate(self.nodes.frame):
            value = binding.read(frame)
            if force or value != values[index]:
                values[index] = value
                await self._write(
                    binding.node, scalar_variant(value, binding.variant), GOOD, source
                )
        for index, analog in enumerate(self.nodes.analog_units):
            if not analog.from_command:
                await self._analog(index, analog.type_name(frame), source)
        version = frame.controller_version
        revision = f"{version.major}.{version.minor}.{version.patch}"
        if revision != self._revision:
            self._revision = revision
            for node in self.nodes.software_revisions:
                await self._write(node, ua.Variant(revision, ua.VariantType.String), GOOD, source)

    async def _state_machines(self, frame: Frame | None, source: datetime) -> None:
        """Each state machine's CurrentState and its Id, when the state changed: Good even
        without a frame (the machine's state is then known: not available)."""
        for index, machine in enumerate(self.nodes.state_machines):
            state = machine.read(frame)
            if state == self._machine_states[index]:
                continue
            self._machine_states[index] = state
            text = ua.Variant(ua.LocalizedText(state.name), ua.VariantType.LocalizedText)
            await self._write(machine.current_state, text, GOOD, source)
            state_id = ua.Variant(state.node, ua.VariantType.NodeId)
            await self._write(machine.state_id, state_id, GOOD, source)

    async def _command(self, image: CommandImage, source: datetime) -> None:
        values = self._command_values
        for index, binding in enumerate(self.nodes.command):
            value = binding.read(image)
            if value != values[index]:
                values[index] = value
                await self._write(
                    binding.node, scalar_variant(value, binding.variant), GOOD, source
                )
        for index, analog in enumerate(self.nodes.analog_units):
            if analog.from_command:
                await self._analog(index, analog.type_name(image), source)

    async def _analog(self, index: int, type_name: str, source: datetime) -> None:
        """An analog channel's unit and range, when its type changed."""
        if self._analog_types[index] == type_name:
            return
        self._analog_types[index] = type_name
        analog = self.nodes.analog_units[index]
        unit, eu_range = analog_unit(type_name)
        extension = ua.VariantType.ExtensionObject
        await self._write(analog.units, ua.Variant(unit.information(), extension), GOOD, source)
        await self._write(analog.range, ua.Variant(eu_range, extension), GOOD, source)

    async def _nameplates(self, identity: Identity, source: datetime) -> None:
        self._identity = identity
        model = ua.Variant(ua.LocalizedText(identity.product_name), ua.VariantType.LocalizedText)
        for node in self.nodes.models:
            await self._write(node, model, GOOD, source)
        serial = ua.Variant(identity.serial_number, ua.VariantType.String)
        for node in self.nodes.serial_numbers:
            await self._write(node, serial, GOOD, source)
        code = ua.Variant(identity.product_code, ua.VariantType.String)
        for node in self.nodes.product_codes:
            await self._write(node, code, GOOD, source)
        uri = ua.Variant(identity.product_instance_uri, ua.VariantType.String)
        for node in self.nodes.product_instance_uris:
            await self._write(node, uri, GOOD, source)
        arm = identity.arm
        for joint_range in self.nodes.joint_ranges:
            joint = arm.joints[joint_range.joint]
            limit = joint.max_speed_deg_s if joint_range.speed else joint.limit_deg
            span = ua.Range(Low=-limit, High=limit)
            variant = ua.Variant(span, ua.VariantType.ExtensionObject)
            await self._write(joint_range.node, variant, GOOD, source)
