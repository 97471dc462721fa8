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

import functools
import time
from collections.abc import Awaitable, Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any, Final

from asyncua import Server, ua
from asyncua.server.internal_subscription import InternalSubscription
from asyncua.server.monitored_item_service import MonitoredItemService
from asyncua.ua import uatypes

from cobot_hmi.arms import ARMS, Arm
from cobot_hmi.codec import CommandImage, Frame
from cobot_hmi.opcua import encoding
from cobot_hmi.opcua.bindings import Binding, CommandBinding, MachineState, RobotNodes
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


_ASYNCUA_WIN_EPOCH: Final = uatypes.datetime_to_win_epoch  # its own module's: never this one
_WIN_EPOCHS: dict[datetime, int] = {}
_WIN_EPOCHS_KEPT: Final = 4096


def win_epoch(dt: datetime) -> int:
    """asyncua's ``datetime_to_win_epoch`` (a DateTime as OPC UA encodes it), remembered.

    asyncua's encoder converts both timestamps of every DataValue it sends through datetime
    arithmetic (a fifth of a notification's encoding); the notifications of one update share
    two timestamps (the frame's receive time, the update's time), so the conversion is asked
    of the same few datetimes thousands of times. The answer is asyncua's own, for an equal
    datetime (equal datetimes are the same instant, or the same naive fields): the bytes on the
    wire do not change. Installed as ``asyncua.ua.datetime_to_win_epoch``, which asyncua's
    ``_DateTime.pack`` looks up at each call (here, once, on import)."""
    known = _WIN_EPOCHS.get(dt)
    if known is None:
        if len(_WIN_EPOCHS) >= _WIN_EPOCHS_KEPT:
            _WIN_EPOCHS.clear()
        known = _WIN_EPOCHS[dt] = _ASYNCUA_WIN_EPOCH(dt)
    return known


ua.datetime_to_win_epoch = win_epoch
encoding.install()  # the notifications' DataValues encoded without asyncua's generic walk

_ASYNCUA_DATACHANGE: Final = MonitoredItemService.datachange_callback
_DISABLED: Final = ua.MonitoringMode.Disabled
_STATUS_VALUE: Final = ua.DataChangeTrigger.StatusValue

Later = list[Callable[[], Awaitable[None]]]
"""What a write still has to await once its value is stored and queued (``RobotValues._store``)."""


def _status_or_value_changed(old: ua.DataValue | None, new: ua.DataValue) -> bool:
    """asyncua's ``MonitoredItemService._is_data_changed`` with the default trigger
    (StatusValue) for a current value that is never None: the same comparisons, in its order,
    without its list of triggers and accessor calls (a StatusCode is compared as asyncua does
    unless it is the very same object)."""
    if old is None:
        return True
    status = old.StatusCode
    if status is not new.StatusCode and status != new.StatusCode:
        return True
    return bool(old.Value != new.Value)


def monitored_change(
    service: MonitoredItemService, handle: int, value: SharedDataValue
) -> InternalSubscription | None:
    """asyncua's ``MonitoredItemService.datachange_callback`` for one of these values, and its
    subscription's ``enqueue_datachange_event``, without a coroutine: the same checks (the
    item's mode, its filter or a change of status or value) and the same queue (a list per
    item, the oldest dropped beyond the item's queue size), the notification made only when it
    goes out, with this value (not a default DataValue and Variant of its own first), and no
    deep copy (``SharedDataValue``: the previous value kept as asyncua keeps it).

    asyncua awaits three coroutines per data change (the callback, the enqueue and the
    publishing trigger) although only the trigger can wait, and only for a subscription that
    publishes at once (no publishing cycle of its own); with a historian on every variable
    they were most of the cost of a write. Returns that subscription when asyncua's trigger
    would publish now (an item's first notification since the last publish, to a subscription
    without a cycle): the caller awaits its ``_trigger_publish``; otherwise ``None``. Kept
    equal to asyncua's own callback by test_opcua_units (the queued notifications compared)."""
    mid = service._monitored_datachange[handle]
    item = service._monitored_items[mid]
    if item.mode == _DISABLED:
        return None
    values = item.mvalue
    old = values.old_dvalue = values.current_dvalue
    values.current_dvalue = value
    flt = item.filter
    if flt:
        if not (
            service._is_data_changed(values, flt.Trigger)
            and service._is_deadband_exceeded(values, flt)
        ):
            return None
    elif not _status_or_value_changed(old, value):
        return None
    event: ua.MonitoredItemNotification = _new(ua.MonitoredItemNotification)
    event.ClientHandle = item.client_handle
    event.Value = value
    subscription = service.isub
    queue = subscription._triggered_datachanges
    queued = queue.get(mid)
    if queued is None:
        queue[mid] = [event]
        if not subscription._task and subscription.data.RevisedPublishingInterval <= 0.0:
            return subscription  # asyncua's _trigger_publish publishes at once
        return None
    size = item.queue_size
    if size != 0 and len(queued) >= size:
        queued.pop(0)
    queued.append(event)
    return None


def tell_monitored_items(callbacks: Mapping[int, Any], value: SharedDataValue) -> Later | None:
    """A variable's monitored items (its value attribute's ``datachange_callbacks``) told of
    ``value`` as asyncua's ``write_attribute_value`` tells them: asyncua's own callbacks at once
    (``monitored_change``), what must still be awaited (a publishing at once, another callback)
    returned in order (``None``, the rule: nothing). Nothing is awaited here, so the dict
    stays as it is while it is walked."""
    later: Later | None = None
    for handle, callback in callbacks.items():
        if getattr(callback, "__func__", None) is _ASYNCUA_DATACHANGE:
            subscription = monitored_change(callback.__self__, handle, value)
            if subscription is None:
                continue
            action: Callable[[], Awaitable[None]] = subscription._trigger_publish
        else:
            action = functools.partial(callback, handle, value)
        if later is None:
            later = []
        later.append(action)
    return later


async def run_later(later: Later) -> None:
    """What ``tell_monitored_items`` left to await, in order."""
    for action in later:
        await action()


def _utc(epoch_s: float) -> datetime:
    return datetime.fromtimestamp(epoch_s, UTC)


class FieldReads:
    """Which of a robot's frame bindings to read for a new frame: those of the fields that
    differ from the last frame's (a field compared whole, in C, instead of each of its
    elements' bindings called and compared: most of a moving robot's 540 variables keep their
    value from one sample to the next), and every binding that may read any field."""

    def __init__(self, bindings: Sequence[Binding]) -> None:
        self._always = [i for i, b in enumerate(bindings) if b.field_position is None]
        by_field: dict[int, list[int]] = {}
        for i, binding in enumerate(bindings):
            if binding.field_position is not None:
                by_field.setdefault(binding.field_position, []).append(i)
        self._by_field = sorted(by_field.items())
        self._last: Frame | None = None

    def indices(self, frame: Frame, *, everything: bool = False) -> list[int] | None:
        """The bindings to read for ``frame``, in their order (``None``: all of them, for the
        first frame or with ``everything``); ``frame`` becomes the last frame."""
        last, self._last = self._last, frame
        if everything or last is None:
            return None
        if frame is last:  # the same bytes decoded once: no field changed
            return list(self._always)
        chosen = list(self._always)
        for position, bound in self._by_field:
            if frame[position] != last[position]:
                chosen += bound
        chosen.sort()
        return chosen


class RobotValues:
    """The values of one robot's variables as last written (see the module docstring)."""

    def __init__(self, server: Server, nodes: RobotNodes) -> None:
        self._aspace = server.iserver.aspace
        self.nodes = nodes
        self._frame_values: list[object] = [None] * len(nodes.frame)
        self._frame_reads = [binding.read for binding in nodes.frame]
        self._frame_attributes: list[Any] = [None] * len(nodes.frame)
        self._frame_reading = FieldReads(nodes.frame)
        self._command_values: list[object] = [None] * len(nodes.command)
        self._command_reads = [binding.read for binding in nodes.command]
        self._command_attributes: list[Any] = [None] * len(nodes.command)
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

    def _attribute(self, node: ua.NodeId) -> Any:
        attribute = self._attributes.get(node)
        if attribute is None:
            attribute = self._attributes[node] = self._aspace[node].attributes[_VALUE]
        return attribute

    def _store(self, attribute: Any, value: SharedDataValue) -> Later | None:
        """One value as asyncua's own ``write_attribute_value`` stores it in a variable's
        value ``attribute`` (the value, then each monitored item's callback), without its
        per-write checks: every variable here is written with its own data type, and a Bad
        status always with a Null value. Its monitored items are told at once
        (``tell_monitored_items``); what must still be awaited is returned for this write's
        caller to await before the next write."""
        self.writes += 1
        attribute.value = value
        attribute.value_callback = None
        callbacks = attribute.datachange_callbacks
        if not callbacks:
            return None
        return tell_monitored_items(callbacks, value)

    async def _write(
        self, node: ua.NodeId, variant: ua.Variant, status: ua.StatusCode, source: datetime
    ) -> None:
        later = self._store(self._attribute(node), shared_value(variant, status, source, self._now))
        if later:
            await run_later(later)

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
        now = self._now = _utc(time.time())  # also the SourceTimestamp of the service's own
        if sample.connection_state != self._state and self.nodes.connection_state is not None:
            self._state = sample.connection_state
            text = ua.Variant(sample.connection_state, ua.VariantType.String)
            await self._write(self.nodes.connection_state, text, GOOD, now)
        if sample.control_holder != self._holder and self.nodes.control_holder is not None:
            self._holder = sample.control_holder
            holder = ua.Variant(sample.control_holder, ua.VariantType.String)
            await self._write(self.nodes.control_holder, holder, GOOD, now)
        if sample.identity is not None and sample.identity != self._identity:
            await self._nameplates(sample.identity, now)
        if sample.command is not None:
            await self._command(sample.command, now)
        if sample.health is not None and sample.health is not self._health_event:
            self._health_event = sample.health
            await self._health(sample.health)
        if not sample.connected:
            if self._frame_status is GOOD:
                await self._frames_status(COMMUNICATION_ERROR, now)
            await self._state_machines(None, now)
            return
        if sample.frame is not None:
            received = _utc(sample.received_at)
            await self._frame(sample.frame, received)
            await self._state_machines(sample.frame, received)

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
        await self._changed(
            self.nodes.frame,
            (self._frame_values, self._frame_reads, self._frame_attributes),
            frame,
            source,
            force=force,
            only=self._frame_reading.indices(frame, everything=force),
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

    async def _changed(
        self,
        bindings: Sequence[Binding | CommandBinding],
        kept: tuple[list[object], list[Callable[[Any], object]], list[Any]],
        record: Frame | CommandImage,
        source: datetime,
        *,
        force: bool = False,
        only: Sequence[int] | None = None,
    ) -> None:
        """Each binding's value read from ``record`` (``only`` those at these indices, in
        order: the others' values are known unchanged); those that differ from the values
        ``kept`` (all with ``force``) written Good at ``source`` and kept. ``kept``: the
        values, the bindings' reads and their value attributes (found at the first write: no
        NodeId hashed per write)."""
        values, reads, attributes = kept
        now, store = self._now, self._store
        indices = range(len(reads)) if only is None else only
        fresh = {i: reads[i](record) for i in indices}
        changed = indices if force else [i for i in indices if fresh[i] != values[i]]
        for index in changed:
            value = values[index] = fresh[index]
            binding = bindings[index]
            attribute = attributes[index]
            if attribute is None:
                attribute = attributes[index] = self._attribute(binding.node)
            variant = scalar_variant(value, binding.variant)
            later = store(attribute, shared_value(variant, GOOD, source, now))
            if later:
                await run_later(later)

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
        await self._changed(
            self.nodes.command,
            (self._command_values, self._command_reads, self._command_attributes),
            image,
            source,
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
