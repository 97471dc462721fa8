"""Layer: service (Sparkplug). The edge node's counters as ``/metrics`` families."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from cobot_hmi.sparkplug.node.device import Device

if TYPE_CHECKING:
    from collections.abc import Mapping

    from cobot_hmi.service.extensions import MetricFamily
    from cobot_hmi.sparkplug.buffer import DiskBuffer
    from cobot_hmi.sparkplug.node.command_handling import CommandHandler
    from cobot_hmi.sparkplug.node.connection import NodeConnection, PrimaryHost
    from cobot_hmi.sparkplug.node.core import NodeStatus, Publisher
    from cobot_hmi.sparkplug.node.replay import Replayer
    from cobot_hmi.sparkplug.node.reports import DeviceReports


def _single(name: str, kind: str, text: str, value: float) -> MetricFamily:
    """A family of one sample without labels."""
    return (name, kind, text, [({}, float(value))])


class NodeMetrics:
    """``metric_families`` for the service's collector: a view of the parts' counters, read at
    each scrape (it changes nothing)."""

    def __init__(
        self,
        *,
        status: NodeStatus,
        connection: NodeConnection,
        publisher: Publisher,
        devices: Mapping[str, Device],
        buffer: DiskBuffer,
        replayer: Replayer,
        reports: DeviceReports,
        commands: CommandHandler,
        host: PrimaryHost,
    ) -> None:
        self.status = status
        self.connection = connection
        self.publisher = publisher
        self.devices = devices
        self.buffer = buffer
        self.replayer = replayer
        self.reports = reports
        self.commands = commands
        self.host = host

    @property
    def malformed(self) -> int:
        """Commands and primary host STATEs not understood."""
        return self.commands.bad_commands + self.host.malformed

    def metric_families(self) -> list[MetricFamily]:
        # In this order since 58f13a2 (tests/test_metrics_exposition.py keeps it).
        return [
            *self._session_families(),
            *self._message_families(),
            *self._buffer_families(),
            *self._work_families(),
        ]

    def _session_families(self) -> list[MetricFamily]:
        """The MQTT session: connected, born, reconnects, refusals."""
        return [
            _single(
                "sparkplug_broker_connected",
                "gauge",
                "1 while the edge node is connected to its MQTT broker",
                self.status.online,
            ),
            _single(
                "sparkplug_born",
                "gauge",
                "1 while the node's births are out (connected, and its primary host online)",
                self.status.active,
            ),
            _single(
                "sparkplug_reconnects_total",
                "counter",
                "MQTT connections after the first one (each one a new bdSeq)",
                self.connection.reconnects,
            ),
            _single(
                "sparkplug_connect_refusals_total",
                "counter",
                "CONNECTs the broker refused (credentials, ACL, protocol)",
                self.connection.connect_refusals,
            ),
        ]

    def _message_families(self) -> list[MetricFamily]:
        """Messages and bytes by type (the node's, then each robot's)."""
        devices = list(self.devices.values())

        def per_device(counter: Callable[[Device], Counter[str]]) -> list[Any]:
            return [
                ({"robot": d.device_name, "type": kind}, float(count))
                for d in devices
                for kind, count in sorted(counter(d).items())
            ]

        return [
            (
                "sparkplug_messages_total",
                "counter",
                "Sparkplug messages by type (node messages have no robot label; "
                "DDATA_buffered went to the disk buffer)",
                [
                    ({"type": kind}, float(n))
                    for kind, n in sorted(self.publisher.node_messages.items())
                ]
                + per_device(lambda d: d.messages),
            ),
            (
                "sparkplug_published_bytes_total",
                "counter",
                "payload bytes published, by message type",
                [
                    ({"type": kind}, float(n))
                    for kind, n in sorted(self.publisher.node_bytes.items())
                ]
                + per_device(lambda d: d.bytes),
            ),
        ]

    def _buffer_families(self) -> list[MetricFamily]:
        """The disk buffer: held, dropped, set aside, replayed."""
        return [
            _single(
                "sparkplug_buffered_messages",
                "gauge",
                "DDATA held on disk for replay",
                self.buffer.records_buffered,
            ),
            _single(
                "sparkplug_buffered_bytes",
                "gauge",
                "bytes the disk buffer holds",
                self.buffer.bytes_buffered,
            ),
            _single(
                "sparkplug_buffer_dropped_total",
                "counter",
                "buffered DDATA dropped (buffer full or off)",
                self.buffer.records_dropped,
            ),
            _single(
                "sparkplug_buffer_set_aside_total",
                "counter",
                "buffered DDATA set aside unreplayed (a segment whose catalogue cannot be read), "
                "kept in the buffer's aside/ folder",
                self.buffer.records_set_aside,
            ),
            _single(
                "sparkplug_replayed_total",
                "counter",
                "buffered DDATA published as historical after a reconnect",
                self.replayer.replayed,
            ),
        ]

    def _work_families(self) -> list[MetricFamily]:
        """Frames the node's queues dropped, its reports' CPU time, the DCMD outcomes."""
        return [
            (
                "sparkplug_frames_dropped_total",
                "counter",
                "frames the edge node's queue dropped before it read them",
                [({"robot": d.device_name}, float(d.dropped)) for d in self.devices.values()],
            ),
            _single(
                "sparkplug_tick_seconds_total",
                "counter",
                "CPU time of the edge node's reports on the web event loop",
                self.reports.tick_seconds,
            ),
            (
                "sparkplug_commands_total",
                "counter",
                "DCMD outcomes",
                [({"outcome": k}, float(v)) for k, v in sorted(self.commands.commands.items())]
                + [({"outcome": "malformed"}, float(self.malformed))],
            ),
        ]
