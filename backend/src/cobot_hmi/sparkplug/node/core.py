"""Layer: service (Sparkplug). What the edge node's parts share: the node's status (connected,
born, stopping), the tasks they start in the background, and the one way a message goes out
(``Publisher``: numbered, published, counted).
"""

from __future__ import annotations

import asyncio
from collections import Counter
from collections.abc import Coroutine
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from cobot_hmi.sparkplug.mqtt_client import queued
from cobot_hmi.sparkplug.node.device import Device
from cobot_hmi.sparkplug.payload import Payload
from cobot_hmi.sparkplug.topics import MessageType

if TYPE_CHECKING:
    import paho.mqtt.client as mqtt

    from cobot_hmi.sparkplug.session import NodeSession


@dataclass
class NodeStatus:
    """The node's state, written by its MQTT connection (``stopping`` by the node), read by
    the parts that decide whether to publish, buffer or wait."""

    online: bool = False
    """Connected to the broker."""
    active: bool = False
    """Born: NBIRTH went out on this connection, so DBIRTH, DDATA and DDEATH may follow."""
    stopping: bool = False
    """The service stops: no new connection, no new command."""


class Background:
    """Tasks the parts start on the web loop (a replay, a DCMD, a reconnect), cancelled
    together when the node stops."""

    def __init__(self) -> None:
        self._tasks: set[asyncio.Task[None]] = set()

    def spawn(self, coroutine: Coroutine[Any, Any, None], name: str) -> None:
        task = asyncio.get_running_loop().create_task(coroutine, name=name)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def cancel(self) -> None:
        """Every task cancelled, and each waited for."""
        tasks = list(self._tasks)
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.gather(*tasks, return_exceptions=True)


class Publisher:
    """The one way a message goes out: numbered (``seq``; ``bdSeq`` per connection, from the
    node session), published on the current MQTT client, counted by type (the node's own
    messages here, a robot's on its ``Device``)."""

    def __init__(self, session: NodeSession) -> None:
        self.session = session
        self.client: mqtt.Client | None = None
        """The current connection's client (the MQTT connection sets it; one per connect)."""
        self.node_messages: Counter[str] = Counter()
        self.node_bytes: Counter[str] = Counter()

    @property
    def bd_seq(self) -> int:
        """The bdSeq of the current (or next) connection: its NDEATH and NBIRTH carry it."""
        return self.session.bd_seq

    def count(self, device: Device | None, kind: str, size: int) -> None:
        if device is None:
            self.node_messages[kind] += 1
            self.node_bytes[kind] += size
        else:
            device.messages[kind] += 1
            device.bytes[kind] += size

    def publish(
        self, topic: str, payload: Payload, device: Device | None, kind: str | None = None
    ) -> bool:
        """Number it (``seq``) and send it (QoS 0: paho queues; its thread writes); ``False``
        (not counted) when paho has no connection to queue it on. Counted as ``kind`` when
        given (a robot's live DDATA, the most of them), else by its topic and whether it is
        historical."""
        if not payload.HasField("seq"):
            payload.seq = self.session.next_seq()
        data = payload.SerializeToString()
        assert self.client is not None
        if not queued(self.client.publish(topic, data, qos=0, retain=False)):
            return False
        if kind is None:
            kind = topic.split("/")[2]
            metrics = payload.metrics
            if metrics and metrics[0].is_historical:  # (a slice would wrap a list of them)
                kind += "_historical"
        self.count(device, kind, len(data))
        return True

    def publish_death(self, topic: str, data: bytes) -> mqtt.MQTTMessageInfo:
        """The NDEATH of a clean leave (QoS 1, no ``seq``): its delivery can be waited for."""
        assert self.client is not None
        info = self.client.publish(topic, data, qos=1)
        self.count(None, MessageType.NDEATH, len(data))
        return info
