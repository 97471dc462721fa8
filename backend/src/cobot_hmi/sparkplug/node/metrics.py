"""Layer: service (Sparkplug). The edge node's counters as ``/metrics`` families."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from cobot_hmi.sparkplug.node.core import NodeCore
from cobot_hmi.sparkplug.node.device import Device

if TYPE_CHECKING:
    from cobot_hmi.service.extensions import MetricFamily


class NodeMetrics(NodeCore):
    """``metric_families`` for the service's collector."""

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
