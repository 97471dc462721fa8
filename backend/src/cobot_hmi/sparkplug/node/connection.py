"""Layer: service (Sparkplug). The edge node's MQTT session: paho's client and its callbacks
(on paho's network thread, each handed to the web loop), connects with the bdSeq and NDEATH
will of each, births once connected (and the primary host online), the primary host's STATE,
and the clean leave.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Final

import orjson

from cobot_hmi.sparkplug.mqtt_client import (
    KEEPALIVE_S,
    BrokerAddress,
    ClientOptions,
    ReconnectBackoff,
    make_client,
)
from cobot_hmi.sparkplug.node.births import BirthWriter, death_payload
from cobot_hmi.sparkplug.node.command_handling import CommandHandler
from cobot_hmi.sparkplug.node.core import Background, NodeStatus, Publisher
from cobot_hmi.sparkplug.node.device import Device, now_ms
from cobot_hmi.sparkplug.topics import MessageType, Topics

if TYPE_CHECKING:
    import paho.mqtt.client as mqtt

log = logging.getLogger(__name__)

HOST_LOSS_MARGIN_MS: Final = 60_000
"""How long before the primary host's offline STATE its alarm transitions are sent again."""


class PrimaryHost:
    """The primary host application's STATE (Sparkplug 3.0: JSON ``online``, ``timestamp``),
    when the settings name one (``host_id``); states older than the newest are ignored."""

    def __init__(self, host_id: str | None) -> None:
        self.host_id = host_id
        self.online = host_id is None
        self.timestamp = -1
        self.malformed = 0
        """STATE messages not understood (counted with the malformed commands)."""

    def read(self, data: bytes) -> bool | None:
        """A STATE message: whether the host is online, or ``None`` when it is not understood
        or older than the state acted on."""
        try:
            state = orjson.loads(data)
            online = state["online"]
            timestamp = state["timestamp"]
            if not isinstance(online, bool) or not isinstance(timestamp, int):
                raise TypeError("online must be a boolean and timestamp an integer")
        except (orjson.JSONDecodeError, KeyError, TypeError) as error:
            self.malformed += 1
            log.warning("Sparkplug: the primary host's STATE is not understood: %s", error)
            return None
        if timestamp < self.timestamp:
            return None  # a state older than the one we act on
        self.timestamp = timestamp
        self.online = online
        return online


class NodeConnection:
    """The MQTT session of one edge node: a paho client per connection (``publisher.client``),
    whose events set ``status`` and call ``births`` and ``commands`` on the web loop."""

    def __init__(
        self,
        *,
        options: ClientOptions,
        topics: Topics,
        host: PrimaryHost,
        devices: Mapping[str, Device],
        publisher: Publisher,
        births: BirthWriter,
        commands: CommandHandler,
        status: NodeStatus,
        background: Background,
    ) -> None:
        self.options = options
        self.topics = topics
        self.host = host
        self.devices = devices
        self.publisher = publisher
        self.births = births
        self.commands = commands
        self.status = status
        self.background = background
        self._connect_sent = False
        """The last attempt opened its socket, so its CONNECT (and bdSeq) went out."""
        self._backoff = ReconnectBackoff()
        """Used on paho's thread only (its callbacks)."""
        self._loop: asyncio.AbstractEventLoop | None = None
        self._cycling = False
        # Counters (``/metrics``).
        self.connections = 0
        self.reconnects = 0
        self.connect_refusals = 0

    @property
    def address(self) -> BrokerAddress:
        return self.options.address

    def start(self) -> None:
        """Connecting in the background, on the running loop."""
        self._loop = asyncio.get_running_loop()
        self._connect()

    async def stop(self) -> None:
        """DDEATHs and NDEATH while still connected, then disconnect (no will is sent then)."""
        client = self.publisher.client
        if client is None:
            return
        if self.status.online:
            await self.births.leave()
        self.status.online = False
        client.disconnect()
        await asyncio.to_thread(client.loop_stop)

    def _connect(self) -> None:
        """A new client (paho's thread and sockets are its own), connecting in the background."""
        client = make_client(self.options)
        client.on_pre_connect = self._on_pre_connect
        client.on_socket_open = self._on_socket_open
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_connect_fail = self._on_connect_fail
        client.on_message = self._on_message
        self.publisher.client = client
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
        bd_seq = self.publisher.session.next_connection(self._connect_sent)
        self._connect_sent = False
        client.will_set(
            self.topics.node_topic(MessageType.NDEATH),
            death_payload(bd_seq),
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
        self._backoff.connected()
        # Subscribed before the NBIRTH, as the specification asks.
        for topic_filter in self.topics.command_filters:
            client.subscribe(topic_filter, qos=1)
        if self.host.host_id is not None:
            client.subscribe(self.topics.state_topic(self.host.host_id), qos=1)
        self._to_loop(self._connected, self.publisher.bd_seq)

    def _on_disconnect(
        self,
        client: mqtt.Client,
        _userdata: object,
        _flags: object,
        reason_code: Any,
        _properties: object,
    ) -> None:
        self._backoff.arm(client)  # paho waits right after this callback, then reconnects
        self._to_loop(self._disconnected, str(reason_code))

    def _on_connect_fail(self, client: mqtt.Client, _userdata: object) -> None:
        """An attempt that got no connection (refused, unreachable): the next wait."""
        self._backoff.arm(client)

    def _on_message(self, _client: mqtt.Client, _userdata: object, message: Any) -> None:
        self._to_loop(self._on_message_in_loop, str(message.topic), bytes(message.payload))

    # ------------------------------------------------------------ the web loop

    def _connect_refused(self, reason: str) -> None:
        self.connect_refusals += 1
        log.warning("Sparkplug: the broker %s refused the connection: %s", self.address, reason)

    def _connected(self, bd_seq: int) -> None:
        if self.status.stopping:
            return
        self.connections += 1
        if self.connections > 1:
            self.reconnects += 1
        log.info("Sparkplug: connected to %s (bdSeq %d)", self.address, bd_seq)
        self.status.online = True
        # With a primary host application: its STATE (retained) says first whether it is up.
        self.host.online = self.host.host_id is None
        if self.host.online:
            self._activate()

    def _activate(self) -> None:
        """Births; each DBIRTH is followed by its robot's buffered data, as historical."""
        self.status.active = True
        self.births.birth_all()

    def _disconnected(self, reason: str) -> None:
        if self.status.online and not self._cycling:
            log.warning("Sparkplug: lost the broker %s: %s", self.address, reason)
        self.status.online = False
        self.status.active = False
        for device in self.devices.values():
            device.born = False

    def _on_message_in_loop(self, topic: str, data: bytes) -> None:
        """A message from the broker: the primary host's STATE, or a command."""
        host_id = self.host.host_id
        if host_id is not None and topic == self.topics.state_topic(host_id):
            self._on_host_state(data)
        else:
            self.commands.on_command(topic, data)

    def _on_host_state(self, data: bytes) -> None:
        """Births when the primary host is online; when it goes offline, NDEATH, disconnect
        and connect again (a new bdSeq), to be born once it is back."""
        online = self.host.read(data)
        if online is None:
            return
        if online and self.status.online and not self.status.active:
            log.info("Sparkplug: the primary host %s is online", self.host.host_id)
            self._activate()
        elif not online and self.status.active:
            log.warning("Sparkplug: the primary host %s went offline", self.host.host_id)
            self.status.active = False  # from now on, DDATA go to the buffer
            # What went out before this STATE came may not have reached it either (its will
            # is published once the broker notices it gone): each robot's next DBIRTH is
            # followed by its alarm transitions since a while before.
            since = now_ms() - HOST_LOSS_MARGIN_MS
            for device in self.devices.values():
                before = device.history_from_ms
                device.history_from_ms = since if before is None else min(before, since)
            self.background.spawn(self._cycle_connection(), "sparkplug reconnect")

    async def _cycle_connection(self) -> None:
        """NDEATH, disconnect, connect again (Sparkplug 3.0 for a primary host gone offline)."""
        client = self.publisher.client
        if client is None:
            return
        self._cycling = True
        try:
            await self.births.leave()
            client.disconnect()
            await asyncio.to_thread(client.loop_stop)
            if not self.status.stopping:
                self._connect()
        finally:
            self._cycling = False
