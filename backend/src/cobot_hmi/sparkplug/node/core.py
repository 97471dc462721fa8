"""Layer: service (Sparkplug). The state the edge node's parts share (settings, devices,
the node session and its bdSeq, the disk buffer, the MQTT client, the counters) and the one
way a message goes out: numbered (``seq``), published, counted.
"""

from __future__ import annotations

import asyncio
import math
import secrets
import time
from collections import Counter
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cobot_hmi.layout import LAYOUT_VERSION, O2T_FIELDS
from cobot_hmi.service.access.auth import Session
from cobot_hmi.service.access.users import Role, User
from cobot_hmi.service.writes.pipeline import Writer
from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.catalogue import Catalogue
from cobot_hmi.sparkplug.mqtt_client import (
    BrokerAddress,
    ClientOptions,
    ReconnectBackoff,
    queued,
)
from cobot_hmi.sparkplug.node.device import Device
from cobot_hmi.sparkplug.payload import Payload
from cobot_hmi.sparkplug.session import NodeSession
from cobot_hmi.sparkplug.topics import Topics

if TYPE_CHECKING:
    import paho.mqtt.client as mqtt

    from cobot_hmi.service.robots.robot import RobotRuntime
    from cobot_hmi.sparkplug.settings import SparkplugSettings


class NodeCore:
    """What the edge node holds: settings, devices, session, buffer, counters; numbering and
    publishing. Build with its settings, the service's state directory and robots."""

    def __init__(
        self,
        settings: SparkplugSettings,
        state_dir: Path,
        robots: Mapping[str, RobotRuntime],
    ) -> None:
        self.address = BrokerAddress.parse(settings.mqtt_url)
        self.topics = Topics(settings.sparkplug_group, settings.sparkplug_node_id)
        self.catalogue = Catalogue(settings.sparkplug_deadbands)
        self.writes_enabled = settings.mqtt_writes
        self.period_s = 1.0 / settings.sparkplug_max_rate_hz
        self.devices: dict[str, Device] = {
            name: Device(robot, number, self.catalogue)
            for number, (name, robot) in enumerate(robots.items(), start=1)
        }
        state = state_dir / "sparkplug"
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
        self._backoff = ReconnectBackoff()
        """Used on paho's thread only (its callbacks)."""
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

    def _spawn(self, coroutine: Any, name: str) -> None:
        task = asyncio.get_running_loop().create_task(coroutine, name=name)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    def _count(self, device: Device | None, kind: str, size: int) -> None:
        if device is None:
            self.node_messages[kind] += 1
            self.node_bytes[kind] += size
        else:
            device.messages[kind] += 1
            device.bytes[kind] += size

    def _publish(self, topic: str, payload: Payload, device: Device | None) -> bool:
        """Number it (``seq``) and send it (QoS 0: paho queues; its thread writes); ``False``
        (not counted) when paho has no connection to queue it on."""
        if not payload.HasField("seq"):
            payload.seq = self.session.next_seq()
        data = payload.SerializeToString()
        assert self._client is not None
        if not queued(self._client.publish(topic, data, qos=0, retain=False)):
            return False
        kind = topic.split("/")[2]
        if any(m.is_historical for m in payload.metrics[:1]):
            kind += "_historical"
        self._count(device, kind, len(data))
        return True
