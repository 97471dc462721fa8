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

This module is the node's MQTT session (paho's client, its callbacks, connects, the primary
host's STATE); its other parts are in ``sparkplug.node``: the devices, births and deaths with
the buffer's replay, the robots' reports, commands, ``/metrics``.

Never imports a route, the app or the CLI.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import orjson

from cobot_hmi.sparkplug.mqtt_client import KEEPALIVE_S, make_client
from cobot_hmi.sparkplug.node.command_handling import CommandHandling
from cobot_hmi.sparkplug.node.metrics import NodeMetrics
from cobot_hmi.sparkplug.node.reports import DeviceReports
from cobot_hmi.sparkplug.topics import MessageType

if TYPE_CHECKING:
    import paho.mqtt.client as mqtt


log = logging.getLogger(__name__)


class EdgeNode(DeviceReports, CommandHandling, NodeMetrics):
    """Build with the service's settings and robots; ``start`` on the web loop; ``stop`` once."""

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
        client.on_connect_fail = self._on_connect_fail
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
        self._backoff.connected()
        # Subscribed before the NBIRTH, as the specification asks.
        for topic_filter in self.topics.command_filters:
            client.subscribe(topic_filter, qos=1)
        if self.primary_host is not None:
            client.subscribe(self.topics.state_topic(self.primary_host), qos=1)
        self._to_loop(self._connected, self._connecting_bd_seq)

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

    def _on_message_in_loop(self, topic: str, data: bytes) -> None:
        """A message from the broker: the primary host's STATE, or a command."""
        if self.primary_host is not None and topic == self.topics.state_topic(self.primary_host):
            self._on_host_state(data)
        else:
            self._on_command(topic, data)

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


__all__ = ["EdgeNode"]
