"""Layer: service (Sparkplug). The service as a Sparkplug B edge node: every robot a device.

Threads: the cyclic thread only appends each frame to this node's bounded queue per robot
(each robot's device is a consumer of its frames, ``robots.frame_notifier``: O(1), drops counted, it
never waits); paho's network thread does the MQTT socket, keep-alive and reconnects and hands
every event to the web event loop; everything else
(reports by exception, births, deaths, the buffer, commands) runs on the web event loop, one
task for every robot waking each at its maximum rate, so all state here has one thread. The
service's alarm, cycle and health events come from its event bus (``node.events``, on the web
loop too) and are reported with the robot's next tick (``event_metrics``).

Per robot and tick: not connected → DDEATH (once); connected again (or a new connection) →
DBIRTH from its newest frame; otherwise a DDATA with what changed (``rbe``), the O→T image,
the control holder and command outcomes, if anything did. While the broker is away the DDATA go
to the disk buffer; after the reconnect come NBIRTH, the DBIRTHs, then the buffered data as
historical. NDEATH is the MQTT will of each connection (and is sent before a clean stop).

``EdgeNode`` composes the parts of ``sparkplug.node``, each an object with one job, built here
with what it needs: the devices, the ``Publisher`` (numbering, publishing, counting), the
``Replayer`` (the buffer after a birth), the ``BirthWriter`` (births and deaths), the
``DeviceReports`` (each robot's ticks), the ``CommandHandler`` (NCMD, DCMD), the
``NodeConnection`` (the MQTT session, the primary host's STATE) and ``NodeMetrics``
(``/metrics``).

Never imports a route, the app or the CLI.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from cobot_hmi.layout import LAYOUT_VERSION
from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.catalogue import Catalogue
from cobot_hmi.sparkplug.event_metrics import alarm_declarations
from cobot_hmi.sparkplug.mqtt_client import BrokerAddress, ClientOptions
from cobot_hmi.sparkplug.node.births import BirthWriter
from cobot_hmi.sparkplug.node.command_handling import CommandHandler, door_writer
from cobot_hmi.sparkplug.node.connection import NodeConnection, PrimaryHost
from cobot_hmi.sparkplug.node.core import Background, NodeStatus, Publisher
from cobot_hmi.sparkplug.node.device import Device
from cobot_hmi.sparkplug.node.events import EventFeed
from cobot_hmi.sparkplug.node.metrics import NodeMetrics
from cobot_hmi.sparkplug.node.replay import Replayer, spool_catalogue
from cobot_hmi.sparkplug.node.reports import DeviceReports
from cobot_hmi.sparkplug.session import NodeSession
from cobot_hmi.sparkplug.topics import Topics

if TYPE_CHECKING:
    from cobot_hmi.service.events.bus import EventBus
    from cobot_hmi.service.extensions import MetricFamily
    from cobot_hmi.service.robots.robot import RobotRuntime
    from cobot_hmi.sparkplug.sparkplug_settings import SparkplugSettings


log = logging.getLogger(__name__)


def client_options(settings: SparkplugSettings, client_id: str) -> ClientOptions:
    return ClientOptions(
        BrokerAddress.parse(settings.mqtt_url),
        client_id,
        settings.mqtt_user,
        settings.mqtt_password,
        settings.mqtt_ca_file,
        settings.mqtt_client_cert,
        settings.mqtt_client_key,
    )


class EdgeNode:
    """Build with the service's settings and robots; ``start`` on the web loop; ``stop`` once."""

    def __init__(
        self,
        settings: SparkplugSettings,
        state_dir: Path,
        robots: Mapping[str, RobotRuntime],
        events: EventBus | None = None,
        hmi_url: str = "",
    ) -> None:
        """``events``: the service's bus, whose alarm, cycle and health events become each
        robot's event metrics; ``hmi_url``: the cell's HMI address for the NBIRTH."""
        self.topics = Topics(settings.sparkplug_group, settings.sparkplug_node_id)
        self.catalogue = Catalogue(settings.sparkplug_deadbands)
        self.client_id = f"cobot-hmi-{self.topics.group}-{self.topics.node}"
        options = client_options(settings, self.client_id)
        self.address = options.address
        # Every alarm of each robot's engine, declared in its births (its set is fixed).
        self.devices: dict[str, Device] = {
            name: Device(robot, number, self.catalogue, alarm_declarations(robot.alarms.all()))
            for number, (name, robot) in enumerate(robots.items(), start=1)
        }
        state = state_dir / "sparkplug"
        # Per layout version: a buffered metric is its robot's catalogue offset (in the alias),
        # which another layout numbers otherwise; each segment also keeps the robots' metric
        # catalogue it was written with (the alarms' metrics depend on the configuration), so
        # that a replay after a restart under another one goes out by name (``replay``).
        self.buffer = DiskBuffer(
            state / f"buffer-layout-{LAYOUT_VERSION}",
            settings.sparkplug_buffer_bytes,
            spool_catalogue(self.devices),
        )
        self.status = NodeStatus()
        self.background = Background()
        self.publisher = Publisher(NodeSession(state / "bdseq"))
        self.events = events
        self.event_feed = EventFeed(self.devices)
        if events is not None:  # from the service's start on: no health event missed
            events.add(self.event_feed)
        self.hmi_url = hmi_url
        self._compose(settings, options)

    def _compose(self, settings: SparkplugSettings, options: ClientOptions) -> None:
        """The parts, each given the parts it works with."""
        self.replayer = Replayer(
            topics=self.topics,
            devices=self.devices,
            buffer=self.buffer,
            publisher=self.publisher,
            status=self.status,
            background=self.background,
        )
        self.births = BirthWriter(
            topics=self.topics,
            catalogue=self.catalogue,
            devices=self.devices,
            publisher=self.publisher,
            replayer=self.replayer,
            hmi_url=self.hmi_url,
        )
        self.reports = DeviceReports(
            topics=self.topics,
            devices=self.devices,
            catalogue=self.catalogue,
            births=self.births,
            publisher=self.publisher,
            buffer=self.buffer,
            status=self.status,
            period_s=1.0 / settings.sparkplug_max_rate_hz,
        )
        self.commands = CommandHandler(
            topics=self.topics,
            devices=self.devices,
            catalogue=self.catalogue,
            births=self.births,
            status=self.status,
            background=self.background,
            writer=door_writer(
                settings.mqtt_user or self.client_id, f"{self.address} ({self.client_id})"
            ),
            writes_enabled=settings.mqtt_writes,
        )
        self.host = PrimaryHost(settings.sparkplug_primary_host or None)
        self.connection = NodeConnection(
            topics=self.topics,
            devices=self.devices,
            options=options,
            host=self.host,
            publisher=self.publisher,
            births=self.births,
            commands=self.commands,
            status=self.status,
            background=self.background,
        )
        self.metrics = NodeMetrics(
            status=self.status,
            connection=self.connection,
            publisher=self.publisher,
            devices=self.devices,
            buffer=self.buffer,
            replayer=self.replayer,
            reports=self.reports,
            commands=self.commands,
            host=self.host,
        )

    async def start(self) -> None:
        self.event_feed.restored()
        self.connection.start()
        log.info(
            "Sparkplug B edge node %s/%s on %s (%d robots)",
            self.topics.group,
            self.topics.node,
            self.address,
            len(self.devices),
        )
        self.reports.start()

    async def stop(self) -> None:
        """DDEATHs and NDEATH while still connected, then disconnect (no will is sent then)."""
        self.status.stopping = True
        await self.reports.stop()
        await self.background.cancel()
        await self.connection.stop()
        if self.events is not None:
            self.events.remove(self.event_feed)
        for device in self.devices.values():
            device.robot.frames.remove(device.registration)

    def metric_families(self) -> list[MetricFamily]:
        return self.metrics.metric_families()

    # ------------------------------------------------------------ what tests and benches read

    @property
    def online(self) -> bool:
        """Connected to the broker."""
        return self.status.online

    @property
    def active(self) -> bool:
        """Born on this connection (NBIRTH went out)."""
        return self.status.active

    @property
    def replayed(self) -> int:
        return self.replayer.replayed

    @property
    def _replaying(self) -> bool:
        return self.replayer.running

    @property
    def connections(self) -> int:
        return self.connection.connections

    @property
    def reconnects(self) -> int:
        return self.connection.reconnects

    @property
    def connect_refusals(self) -> int:
        return self.connection.connect_refusals

    @property
    def bad_commands(self) -> int:
        """Commands and primary host STATEs not understood (``/metrics``' malformed)."""
        return self.metrics.malformed


__all__ = ["EdgeNode"]
