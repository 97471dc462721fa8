"""Layer: service (Sparkplug). The service as a Sparkplug B edge node: every robot a device.

Threads: the cyclic thread only appends each frame to this node's bounded queue per robot
(``Hub.subscribe``: O(1), drops counted, it never waits); paho's network thread does the MQTT
socket, keep-alive and reconnects and hands every event to the web event loop; everything else
(reports by exception, births, deaths, the buffer, commands) runs on the web event loop, one
task per robot waking at the robot's maximum rate, so all state here has one thread.

Per robot and tick: not connected → DDEATH (once); connected again (or a new connection) →
DBIRTH from its newest frame; otherwise a DDATA with what changed (``rbe``), the O→T image,
the control holder and command outcomes, if anything did. While the broker is away the DDATA go
to the disk buffer; after the reconnect come NBIRTH, the DBIRTHs, then the buffered data as
historical. NDEATH is the MQTT will of each connection (and is sent before a clean stop).

Never imports a route, the app or the CLI.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import secrets
import time
from collections import Counter, deque
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import orjson

from cobot_hmi.codec import CommandImage, Frame
from cobot_hmi.layout import LAYOUT_VERSION, O2T_FIELDS
from cobot_hmi.service.access.auth import Session
from cobot_hmi.service.access.users import Role, User
from cobot_hmi.service.robots.frames import FrameRecord, Runs
from cobot_hmi.service.writes.pipeline import Writer
from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.catalogue import (
    ALIAS_STRIDE,
    BD_SEQ,
    REBIRTH,
    Catalogue,
    MetricDef,
    state_name,
)
from cobot_hmi.sparkplug.catalogue import (
    Role as MetricRole,
)
from cobot_hmi.sparkplug.commands import (
    DeviceCommand,
    execute,
    parse_device_command,
    wants_rebirth,
)
from cobot_hmi.sparkplug.mqtt_client import (
    KEEPALIVE_S,
    BrokerAddress,
    ClientOptions,
    make_client,
)
from cobot_hmi.sparkplug.payload import (
    DataType,
    MetricValue,
    Payload,
    PayloadError,
    Property,
    add_metric,
    make_payload,
    parse_payload,
)
from cobot_hmi.sparkplug.rbe import Change, Reporter
from cobot_hmi.sparkplug.session import NodeSession
from cobot_hmi.sparkplug.topics import MessageType, Topics

if TYPE_CHECKING:
    import paho.mqtt.client as mqtt

    from cobot_hmi.service.api.metrics import MetricFamily
    from cobot_hmi.service.robots.robot import RobotRuntime
    from cobot_hmi.service.settings import ServiceSettings

log = logging.getLogger(__name__)

QUEUE_FRAMES: Final = 4096
"""Frames a robot's queue holds between two ticks (~40 s at RPI 10 ms)."""
REPLAY_BATCH: Final = 50
"""Historical messages published between two yields of the web loop."""
LAYOUT_VERSION_METRIC: Final = "Node Info/Layout Version"


def _now_ms() -> int:
    return int(time.time() * 1000)


class Device:
    """One robot as a Sparkplug device: its frames, reporter and what was last reported.

    A consumer of the robot's frames (``robots.frames``) on the web loop: ``on_frames`` keeps
    them (bounded: the oldest dropped and counted) and wakes the device's loop, which reports
    at most every ``period_s``, right after frames arrived."""

    name: Final = "sparkplug"
    runs: Final = Runs.LOOP
    queue_frames: Final = QUEUE_FRAMES

    def __init__(self, robot: RobotRuntime, number: int, catalogue: Catalogue) -> None:
        self.robot = robot
        self.device_name = robot.name
        self.alias_base = number * ALIAS_STRIDE
        self.pending: deque[FrameRecord] = deque(maxlen=QUEUE_FRAMES)
        """Frames since the last report."""
        self.pending_dropped = 0
        self.arrived = asyncio.Event()
        self.registration = robot.frames.add(self)
        self.reporter = Reporter(catalogue)
        self.alive = False
        """Reported since its connection came up (a DBIRTH was made, sent or not)."""
        self.born = False
        """A DBIRTH went out in the current MQTT session."""
        self.connects_seen = -1
        self.frame: tuple[Frame, float] | None = None
        """The newest frame seen, and its receive time."""
        self.command: CommandImage | None = None
        self.holder = ""
        self.outcome: tuple[str, str] = ("", "")
        self.outcome_pending = False
        self.reported_at = -math.inf
        """``loop.time()`` of the last DDATA (published or buffered): the next one waits for
        ``period_s`` after it (the maximum rate)."""
        self.messages: Counter[str] = Counter()
        self.bytes: Counter[str] = Counter()

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        pending = self.pending
        overflow = len(pending) + len(records) - QUEUE_FRAMES
        if overflow > 0:
            self.pending_dropped += overflow
        pending.extend(records)
        self.arrived.set()

    def take(self) -> list[FrameRecord]:
        """The frames since the last report, oldest first."""
        items = list(self.pending)
        self.pending.clear()
        return items

    @property
    def dropped(self) -> int:
        """Frames lost before a report saw them (the notifier's queue and ``pending``)."""
        return self.registration.dropped + self.pending_dropped


class EdgeNode:
    """Build with the service's settings and robots; ``start`` on the web loop; ``stop`` once."""

    def __init__(self, settings: ServiceSettings, robots: Mapping[str, RobotRuntime]) -> None:
        self.address = BrokerAddress.parse(settings.mqtt_url)
        self.topics = Topics(settings.sparkplug_group, settings.sparkplug_node_id)
        self.catalogue = Catalogue(settings.sparkplug_deadbands)
        self.writes_enabled = settings.mqtt_writes
        self.period_s = 1.0 / settings.sparkplug_max_rate_hz
        self.devices: dict[str, Device] = {
            name: Device(robot, number, self.catalogue)
            for number, (name, robot) in enumerate(robots.items(), start=1)
        }
        state = settings.state_dir / "sparkplug"
        self.session = NodeSession(state / "bdseq")
        # Per layout version: a buffered metric is its robot's catalogue offset (in the alias),
        # which another layout numbers otherwise.
        self.buffer = DiskBuffer(
            state / f"buffer-layout-{LAYOUT_VERSION}", settings.sparkplug_buffer_bytes
        )
        self.client_id = f"cobot-hmi-{self.topics.group}-{self.topics.node}"
        identity = settings.mqtt_user or self.client_id
        self.options = ClientOptions(
            self.address,
            self.client_id,
            settings.mqtt_user,
            settings.mqtt_password,
            settings.mqtt_ca_file,
            settings.mqtt_client_cert,
            settings.mqtt_client_key,
        )
        # The MQTT door's one writer: control taken by DCMD belongs to this session, which is
        # no login (its token is never handed out) and never expires.
        user = User(f"mqtt:{identity}", Role.OPERATOR)
        session = Session(secrets.token_urlsafe(24), user, time.time(), math.inf)
        self.writer = Writer(user.name, user.role, f"{self.address} ({self.client_id})", session)
        self.online = False
        """Connected to the broker."""
        self.active = False
        """Born: NBIRTH went out on this connection, so DBIRTH, DDATA and DDEATH may follow."""
        self.primary_host = settings.sparkplug_primary_host or None
        self._host_online = self.primary_host is None
        self._host_timestamp = -1
        self._stopping = False
        self._connect_sent = False
        """The last attempt opened its socket, so its CONNECT (and bdSeq) went out."""
        self._connecting_bd_seq = self.session.bd_seq
        self._client: mqtt.Client | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._tasks: list[asyncio.Task[None]] = []
        self._background: set[asyncio.Task[None]] = set()
        self._replaying = False
        self._cycling = False
        self._replay_again = False
        self._command_offsets = {
            f.name: next(m.offset for m in self.catalogue.command_metrics if m.field == f.name)
            for f in O2T_FIELDS
        }
        # Counters (``/metrics``).
        self.connections = 0
        self.reconnects = 0
        self.connect_refusals = 0
        self.node_messages: Counter[str] = Counter()
        self.node_bytes: Counter[str] = Counter()
        self.replayed = 0
        self.commands: Counter[str] = Counter()
        self.bad_commands = 0
        self.tick_seconds = 0.0
        """CPU time of the robots' ticks on the web loop (reports, encoding, publishing calls):
        the thread's own, so a busy machine's preemptions do not count."""

    # ------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._connect()
        log.info(
            "Sparkplug B edge node %s/%s on %s (%d robots)",
            self.topics.group,
            self.topics.node,
            self.address,
            len(self.devices),
        )
        for device in self.devices.values():
            self._tasks.append(
                asyncio.create_task(
                    self._device_loop(device), name=f"sparkplug {device.device_name}"
                )
            )

    async def stop(self) -> None:
        """DDEATHs and NDEATH while still connected, then disconnect (no will is sent then)."""
        self._stopping = True
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks.clear()
        for task in list(self._background):
            task.cancel()
        if self._background:
            await asyncio.gather(*self._background, return_exceptions=True)
        client = self._client
        if client is None:
            return
        if self.online:
            for device in self.devices.values():
                if device.born:
                    self._publish_device_death(device)
            payload = self._death_payload(self._connecting_bd_seq)
            info = client.publish(self.topics.node_topic(MessageType.NDEATH), payload, qos=1)
            self._count(None, MessageType.NDEATH, len(payload))
            with contextlib.suppress(RuntimeError, ValueError):
                await asyncio.to_thread(info.wait_for_publish, 2.0)
        self.online = False
        client.disconnect()
        await asyncio.to_thread(client.loop_stop)
        for device in self.devices.values():
            device.robot.frames.remove(device.registration)

    def _connect(self) -> None:
        """A new client (paho's thread and sockets are its own), connecting in the background."""
        client = make_client(self.options)
        client.on_pre_connect = self._on_pre_connect
        client.on_socket_open = self._on_socket_open
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        self._client = client
        client.connect_async(self.address.host, self.address.port, KEEPALIVE_S)
        client.loop_start()

    # ------------------------------------------------------------ paho's thread

    def _to_loop(self, callback: Callable[..., None], *args: Any) -> None:
        loop = self._loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
                loop.call_soon_threadsafe(callback, *args)

    def _on_pre_connect(self, client: mqtt.Client, _userdata: object) -> None:
        """Before every CONNECT: the next bdSeq, and the NDEATH carrying it as the will."""
        bd_seq = self.session.next_connection(self._connect_sent)
        self._connect_sent = False
        self._connecting_bd_seq = bd_seq
        client.will_set(
            self.topics.node_topic(MessageType.NDEATH),
            self._death_payload(bd_seq),
            qos=1,
            retain=False,
        )

    def _on_socket_open(self, _client: mqtt.Client, _userdata: object, _socket: object) -> None:
        self._connect_sent = True  # paho sends CONNECT right after opening the socket

    def _on_connect(
        self,
        client: mqtt.Client,
        _userdata: object,
        _flags: object,
        reason_code: Any,
        _properties: object,
    ) -> None:
        if reason_code.is_failure:
            self._to_loop(self._connect_refused, str(reason_code))
            return
        # Subscribed before the NBIRTH, as the specification asks.
        for topic_filter in self.topics.command_filters:
            client.subscribe(topic_filter, qos=1)
        if self.primary_host is not None:
            client.subscribe(self.topics.state_topic(self.primary_host), qos=1)
        self._to_loop(self._connected, self._connecting_bd_seq)

    def _on_disconnect(
        self,
        _client: mqtt.Client,
        _userdata: object,
        _flags: object,
        reason_code: Any,
        _properties: object,
    ) -> None:
        self._to_loop(self._disconnected, str(reason_code))

    def _on_message(self, _client: mqtt.Client, _userdata: object, message: Any) -> None:
        self._to_loop(self._on_command, str(message.topic), bytes(message.payload))

    # ------------------------------------------------------------ the web loop: the session

    def _connect_refused(self, reason: str) -> None:
        self.connect_refusals += 1
        log.warning("Sparkplug: the broker %s refused the connection: %s", self.address, reason)

    def _connected(self, bd_seq: int) -> None:
        if self._stopping:
            return
        self.connections += 1
        if self.connections > 1:
            self.reconnects += 1
        log.info("Sparkplug: connected to %s (bdSeq %d)", self.address, bd_seq)
        self.online = True
        # With a primary host application: its STATE (retained) says first whether it is up.
        self._host_online = self.primary_host is None
        if self._host_online:
            self._activate()

    def _activate(self) -> None:
        """Births; each DBIRTH is followed by its robot's buffered data, as historical."""
        self.active = True
        self._birth_all()

    def _disconnected(self, reason: str) -> None:
        if self.online and not self._cycling:
            log.warning("Sparkplug: lost the broker %s: %s", self.address, reason)
        self.online = False
        self.active = False
        for device in self.devices.values():
            device.born = False

    def _on_host_state(self, data: bytes) -> None:
        """The primary host application's STATE (Sparkplug 3.0: JSON ``online``,
        ``timestamp``): births when it is online; when it goes offline, NDEATH, disconnect and
        connect again (a new bdSeq), to be born once it is back. Older states are ignored."""
        try:
            state = orjson.loads(data)
            online = state["online"]
            timestamp = state["timestamp"]
            if not isinstance(online, bool) or not isinstance(timestamp, int):
                raise TypeError("online must be a boolean and timestamp an integer")
        except (orjson.JSONDecodeError, KeyError, TypeError) as error:
            self.bad_commands += 1
            log.warning("Sparkplug: the primary host's STATE is not understood: %s", error)
            return
        if timestamp < self._host_timestamp:
            return  # a state older than the one we act on
        self._host_timestamp = timestamp
        self._host_online = online
        if online and self.online and not self.active:
            log.info("Sparkplug: the primary host %s is online", self.primary_host)
            self._activate()
        elif not online and self.active:
            log.warning("Sparkplug: the primary host %s went offline", self.primary_host)
            self.active = False  # from now on, DDATA go to the buffer
            self._spawn(self._cycle_connection(), "sparkplug reconnect")

    async def _cycle_connection(self) -> None:
        """NDEATH, disconnect, connect again (Sparkplug 3.0 for a primary host gone offline)."""
        client = self._client
        if client is None:
            return
        self._cycling = True
        try:
            for device in self.devices.values():
                if device.born:
                    self._publish_device_death(device)
            payload = self._death_payload(self._connecting_bd_seq)
            info = client.publish(self.topics.node_topic(MessageType.NDEATH), payload, qos=1)
            self._count(None, MessageType.NDEATH, len(payload))
            with contextlib.suppress(RuntimeError, ValueError):
                await asyncio.to_thread(info.wait_for_publish, 2.0)
            client.disconnect()
            await asyncio.to_thread(client.loop_stop)
            if not self._stopping:
                self._connect()
        finally:
            self._cycling = False

    def _birth_all(self) -> None:
        """NBIRTH (seq 0), then a DBIRTH for every robot that is up."""
        payload = make_payload(_now_ms(), self.session.birth_seq())
        now = _now_ms()
        add_metric(
            payload,
            alias=None,
            name=BD_SEQ,
            timestamp_ms=now,
            datatype=DataType.INT64,
            value=self._connecting_bd_seq,
        )
        add_metric(
            payload,
            alias=None,
            name=REBIRTH,
            timestamp_ms=now,
            datatype=DataType.BOOLEAN,
            value=False,
        )
        add_metric(
            payload,
            alias=None,
            name=LAYOUT_VERSION_METRIC,
            timestamp_ms=now,
            datatype=DataType.UINT32,
            value=LAYOUT_VERSION,
        )
        self._publish(self.topics.node_topic(MessageType.NBIRTH), payload, None)
        for device in self.devices.values():
            device.born = False
            if device.alive:
                self._publish_device_birth(device)

    def _death_payload(self, bd_seq: int) -> bytes:
        payload = make_payload(_now_ms(), None)
        add_metric(
            payload,
            alias=None,
            name=BD_SEQ,
            timestamp_ms=_now_ms(),
            datatype=DataType.INT64,
            value=bd_seq,
        )
        return payload.SerializeToString()

    # ------------------------------------------------------------ publishing

    def _count(self, device: Device | None, kind: str, size: int) -> None:
        if device is None:
            self.node_messages[kind] += 1
            self.node_bytes[kind] += size
        else:
            device.messages[kind] += 1
            device.bytes[kind] += size

    def _publish(self, topic: str, payload: Payload, device: Device | None) -> None:
        """Number it (``seq``) and send it (QoS 0: paho queues; its thread writes)."""
        if not payload.HasField("seq"):
            payload.seq = self.session.next_seq()
        data = payload.SerializeToString()
        assert self._client is not None
        self._client.publish(topic, data, qos=0, retain=False)
        kind = topic.split("/")[2]
        if any(m.is_historical for m in payload.metrics[:1]):
            kind += "_historical"
        self._count(device, kind, len(data))

    def _publish_device_birth(self, device: Device) -> None:
        frame_item = device.frame
        if frame_item is None:
            return
        frame, received_at = frame_item
        payload = make_payload(_now_ms(), None)
        stamp = int(received_at * 1000)
        now = _now_ms()
        values = self._device_values(device, frame)
        for metric, value in zip(self.catalogue.metrics, values, strict=True):
            add_metric(
                payload,
                alias=device.alias_base + metric.offset,
                name=metric.name,
                timestamp_ms=stamp if metric.role is not MetricRole.STATUS else now,
                datatype=metric.datatype,
                value=value,
                properties=self._birth_properties(metric, value),
            )
        self._publish(
            self.topics.device_topic(MessageType.DBIRTH, device.device_name), payload, device
        )
        device.born = True
        if self.buffer.records_buffered:  # its history, if it has some, after its birth
            self._replay_again = True
            if not self._replaying:
                self._spawn(self._replay(), "sparkplug replay")

    def _publish_device_death(self, device: Device) -> None:
        payload = make_payload(_now_ms(), None)
        self._publish(
            self.topics.device_topic(MessageType.DDEATH, device.device_name), payload, device
        )
        device.born = False

    @staticmethod
    def _birth_properties(metric: MetricDef, value: MetricValue) -> list[Property]:
        properties = []
        if metric.unit:
            properties.append(Property("engUnit", DataType.STRING, metric.unit))
        if metric.description:
            properties.append(Property("description", DataType.STRING, metric.description))
        if metric.role is MetricRole.ANALOG:
            properties.append(Property("deadband", DataType.DOUBLE, metric.deadband))
        if metric.writable:
            properties.append(Property("writable", DataType.BOOLEAN, True))
        name = state_name(metric, value)
        if name is not None:
            properties.append(Property("name", DataType.STRING, name))
        return properties

    def _device_values(self, device: Device, frame: Frame) -> list[MetricValue]:
        """Every metric's current value, in the catalogue's order (a birth)."""
        values: list[MetricValue] = []
        for metric in self.catalogue.metrics:
            if metric.role in (MetricRole.DISCRETE, MetricRole.ANALOG):
                field_value = getattr(frame, metric.field or "")
                values.append(field_value if metric.index is None else field_value[metric.index])
        command = device.command
        for metric in self.catalogue.command_metrics:
            values.append(
                getattr(command, metric.field or "")[metric.index or 0]
                if command is not None
                else False
            )
        values.extend([device.holder, False, False, device.outcome[0], device.outcome[1]])
        return values

    # ------------------------------------------------------------ the web loop: ticks

    async def _device_loop(self, device: Device) -> None:
        """A tick at most every ``period_s``, each right after a frame arrived: the newest frame
        is then at its freshest when reported (one wake-up per tick from the cyclic thread,
        its ``on_frames``)."""
        loop = asyncio.get_running_loop()
        last = loop.time()
        while True:
            due = max(last, device.reported_at) + self.period_s
            await asyncio.sleep(max(0.0, due - loop.time()))
            if device.robot.down_since is None:
                device.arrived.clear()
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(self.period_s):
                        await device.arrived.wait()
            last = loop.time()
            started = time.thread_time()
            try:
                self._tick(device)
            except Exception:  # a bug here must not end the robot's reports for good
                log.exception("Sparkplug tick of %s failed", device.device_name)
            self.tick_seconds += time.thread_time() - started

    def _tick(self, device: Device) -> None:
        robot = device.robot
        items = device.take()
        connected = robot.down_since is None
        if device.alive and (not connected or robot.connects != device.connects_seen):
            device.alive = False
            if device.born and self.active:
                self._publish_device_death(device)
            device.born = False
        if not connected:
            return
        if items:
            device.frame = (items[-1][2], items[-1][1])
        if not device.alive:
            if not items:
                return  # no frame of this connection yet
            device.connects_seen = robot.connects
            device.alive = True
            device.reporter.baseline(items[-1][2])
            self._read_status(device)
            if self.active:
                self._publish_device_birth(device)
            return
        changes = device.reporter.discrete_changes(items)
        if items:
            newest = items[-1]
            changes.extend(device.reporter.analog_changes(newest[2], newest[1]))
        changes.extend(self._status_changes(device))
        if changes:
            self._report(device, changes)

    def _read_status(self, device: Device) -> None:
        with contextlib.suppress(AssertionError):  # no originator yet
            device.command = device.robot.link.command
        holder = device.robot.control.holder
        device.holder = holder.user if holder is not None else ""

    def _status_changes(self, device: Device) -> list[Change]:
        """The O→T image, the control holder and command outcomes, when they changed."""
        now = _now_ms()
        changes: list[Change] = []
        before = device.command
        holder_before = device.holder
        self._read_status(device)
        command = device.command
        if command is not None and before is not None and command != before:
            for f in O2T_FIELDS:
                new, old = getattr(command, f.name), getattr(before, f.name)
                if new != old:
                    first = self._command_offsets[f.name]
                    changes.extend(
                        (first + i, a, now)
                        for i, (a, b) in enumerate(zip(new, old, strict=True))
                        if a != b
                    )
        if device.holder != holder_before:
            changes.append((self.catalogue.control_holder.offset, device.holder, now))
        if device.outcome_pending:
            device.outcome_pending = False
            outcome, reason = device.outcome
            changes.append((self.catalogue.write_outcome.offset, outcome, now))
            changes.append((self.catalogue.write_reason.offset, reason, now))
        return changes

    def _report(self, device: Device, changes: list[Change]) -> None:
        """A DDATA: published when born, buffered on disk while the broker is away."""
        # The payload's time and the rate's reference are one instant.
        device.reported_at = asyncio.get_running_loop().time()
        payload = make_payload(_now_ms(), None)
        metrics = self.catalogue.metrics
        for offset, value, stamp in changes:
            metric = metrics[offset]
            name = state_name(metric, value)
            add_metric(
                payload,
                alias=device.alias_base + offset,
                timestamp_ms=stamp,
                datatype=metric.datatype,
                value=value,
                properties=(Property("name", DataType.STRING, name),) if name else (),
            )
        topic = self.topics.device_topic(MessageType.DDATA, device.device_name)
        if self.active and device.born:
            self._publish(topic, payload, device)
        elif not self.active and self.buffer.append(topic, payload.SerializeToString()):
            device.messages["DDATA_buffered"] += 1

    # ------------------------------------------------------------ the buffer

    async def _replay(self) -> None:
        """The buffered DDATA, oldest first, marked historical, each after its robot's DBIRTH
        (a robot not born yet keeps its records for a replay after its birth)."""
        self._replaying = True
        try:
            self._replay_again = True
            while self._replay_again and self.active:
                self._replay_again = False
                for path in self.buffer.sealed():
                    if not await self._replay_segment(path):
                        return
        finally:
            self._replaying = False

    async def _replay_segment(self, path: Path) -> bool:
        """One segment; ``False`` when the node stopped being born midway."""
        records = self.buffer.read(path)
        deferred: list[tuple[str, bytes]] = []
        for index, (topic, data) in enumerate(records):
            if not self.active:
                self.buffer.put_back(path, deferred + records[index:])
                return False
            try:
                payload = parse_payload(data)
            except PayloadError:
                continue
            parsed = self.topics.parse(topic)
            device = self.devices.get(parsed.device or "") if parsed else None
            if device is None:  # buffered by a run with other robots or ids
                self.buffer.records_dropped += 1
                continue
            if not device.born:
                deferred.append((topic, data))
                continue
            for metric in payload.metrics:
                # The robot's place in the settings may have changed since.
                metric.alias = device.alias_base + metric.alias % ALIAS_STRIDE
                metric.is_historical = True
            self._publish(topic, payload, device)
            self.replayed += 1
            if index % REPLAY_BATCH == REPLAY_BATCH - 1:
                await asyncio.sleep(0.01)  # let paho's thread drain its queue
        if deferred:
            self.buffer.put_back(path, deferred)
        else:
            self.buffer.finish(path)
        return True

    # ------------------------------------------------------------ commands

    def _spawn(self, coroutine: Any, name: str) -> None:
        task = asyncio.get_running_loop().create_task(coroutine, name=name)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    def _on_command(self, topic: str, data: bytes) -> None:
        if self.primary_host is not None and topic == self.topics.state_topic(self.primary_host):
            self._on_host_state(data)
            return
        parsed = self.topics.parse(topic)
        if parsed is None or self._stopping:
            return
        try:
            payload = parse_payload(data)
        except PayloadError as error:
            self.bad_commands += 1
            log.warning("Sparkplug: %s: %s", topic, error)
            return
        if parsed.message_type is MessageType.NCMD:
            if wants_rebirth(payload) and self.active:
                log.info("Sparkplug: rebirth asked (NCMD)")
                self._birth_all()
            return
        if parsed.message_type is not MessageType.DCMD:
            return
        device = self.devices.get(parsed.device or "")
        if device is None:
            self.bad_commands += 1
            log.warning("Sparkplug: DCMD for an unknown robot %r", parsed.device)
            return
        command = parse_device_command(payload, self.catalogue, device.alias_base)
        if command.empty:
            return
        self._spawn(
            self._run_command(device, command, topic), f"sparkplug dcmd {device.device_name}"
        )

    async def _run_command(self, device: Device, command: DeviceCommand, topic: str) -> None:
        try:
            result = await execute(
                device.robot,
                self.writer,
                command,
                origin=f"MQTT DCMD {topic}",
                writes_enabled=self.writes_enabled,
            )
        except Exception as error:  # the store or the link failed: say so, stay up
            log.exception("Sparkplug DCMD to %s failed", device.device_name)
            device.outcome = ("error", f"{type(error).__name__}: {error}")
        else:
            device.outcome = (result.outcome, result.reason)
        self.commands[device.outcome[0]] += 1
        device.outcome_pending = True

    # ------------------------------------------------------------ /metrics

    def metric_families(self) -> list[MetricFamily]:
        devices = list(self.devices.values())

        def per_device(counter: Callable[[Device], Counter[str]]) -> list[Any]:
            return [
                ({"robot": d.device_name, "type": kind}, float(count))
                for d in devices
                for kind, count in sorted(counter(d).items())
            ]

        node_label = "type"
        return [
            (
                "sparkplug_broker_connected",
                "gauge",
                "1 while the edge node is connected to its MQTT broker",
                [({}, float(self.online))],
            ),
            (
                "sparkplug_born",
                "gauge",
                "1 while the node's births are out (connected, and its primary host online)",
                [({}, float(self.active))],
            ),
            (
                "sparkplug_reconnects_total",
                "counter",
                "MQTT connections after the first one (each one a new bdSeq)",
                [({}, float(self.reconnects))],
            ),
            (
                "sparkplug_connect_refusals_total",
                "counter",
                "CONNECTs the broker refused (credentials, ACL, protocol)",
                [({}, float(self.connect_refusals))],
            ),
            (
                "sparkplug_messages_total",
                "counter",
                "Sparkplug messages by type (node messages have no robot label; "
                "DDATA_buffered went to the disk buffer)",
                [
                    ({node_label: kind}, float(count))
                    for kind, count in sorted(self.node_messages.items())
                ]
                + per_device(lambda d: d.messages),
            ),
            (
                "sparkplug_published_bytes_total",
                "counter",
                "payload bytes published, by message type",
                [
                    ({node_label: kind}, float(size))
                    for kind, size in sorted(self.node_bytes.items())
                ]
                + per_device(lambda d: d.bytes),
            ),
            (
                "sparkplug_buffered_messages",
                "gauge",
                "DDATA held on disk for replay",
                [({}, float(self.buffer.records_buffered))],
            ),
            (
                "sparkplug_buffered_bytes",
                "gauge",
                "bytes the disk buffer holds",
                [({}, float(self.buffer.bytes_buffered))],
            ),
            (
                "sparkplug_buffer_dropped_total",
                "counter",
                "buffered DDATA dropped (buffer full or off)",
                [({}, float(self.buffer.records_dropped))],
            ),
            (
                "sparkplug_replayed_total",
                "counter",
                "buffered DDATA published as historical after a reconnect",
                [({}, float(self.replayed))],
            ),
            (
                "sparkplug_frames_dropped_total",
                "counter",
                "frames the edge node's queue dropped before it read them",
                [({"robot": d.device_name}, float(d.dropped)) for d in devices],
            ),
            (
                "sparkplug_tick_seconds_total",
                "counter",
                "CPU time of the edge node's reports on the web event loop",
                [({}, self.tick_seconds)],
            ),
            (
                "sparkplug_commands_total",
                "counter",
                "DCMD outcomes",
                [({"outcome": k}, float(v)) for k, v in sorted(self.commands.items())]
                + [({"outcome": "malformed"}, float(self.bad_commands))],
            ),
        ]
