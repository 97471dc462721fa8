"""Layer: service (Sparkplug). Births and deaths: NBIRTH (bdSeq, Rebirth, the layout
version), each robot's DBIRTH (every metric with its properties) and DDEATH, the NDEATH
payload (the MQTT will), and after a DBIRTH the disk buffer's DDATA replayed as historical.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.layout import LAYOUT_VERSION
from cobot_hmi.sparkplug.catalogue import ALIAS_STRIDE, BD_SEQ, REBIRTH, MetricDef, state_name
from cobot_hmi.sparkplug.catalogue import Role as MetricRole
from cobot_hmi.sparkplug.node.core import NodeCore
from cobot_hmi.sparkplug.node.device import Device, now_ms
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
from cobot_hmi.sparkplug.topics import MessageType

REPLAY_BATCH: Final = 50
"""Historical messages published between two yields of the web loop."""
LAYOUT_VERSION_METRIC: Final = "Node Info/Layout Version"


class Births(NodeCore):
    """NBIRTH, DBIRTH, DDEATH and the replay of the buffer after the births."""

    def _birth_all(self) -> None:
        """NBIRTH (seq 0), then a DBIRTH for every robot that is up."""
        payload = make_payload(now_ms(), self.session.birth_seq())
        now = now_ms()
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
        payload = make_payload(now_ms(), None)
        add_metric(
            payload,
            alias=None,
            name=BD_SEQ,
            timestamp_ms=now_ms(),
            datatype=DataType.INT64,
            value=bd_seq,
        )
        return payload.SerializeToString()

    def _publish_device_birth(self, device: Device) -> None:
        frame_item = device.frame
        if frame_item is None:
            return
        frame, received_at = frame_item
        payload = make_payload(now_ms(), None)
        stamp = int(received_at * 1000)
        now = now_ms()
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
                # Marked here, not when the task first runs: the next robot's DBIRTH, in the
                # same turn of the loop, must find it running (one replay, not one per birth).
                self._replaying = True
                self._spawn(self._replay(), "sparkplug replay")

    def _publish_device_death(self, device: Device) -> None:
        payload = make_payload(now_ms(), None)
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

    # ------------------------------------------------------------ the buffer

    async def _replay(self) -> None:
        """The buffered DDATA, oldest first, marked historical, each after its robot's DBIRTH
        (a robot not born yet keeps its records for a replay after its birth). One at a time:
        ``_replaying`` is set by whoever spawns it; a birth meanwhile asks for another pass."""
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
        """One segment, in order; ``False`` when the node stopped being born midway (what did
        not go out is kept, still the oldest, for the next replay)."""
        records = self.buffer.read(path)
        deferred: list[tuple[str, bytes]] = []
        waiting: set[str] = set()
        """Robots with a record deferred: their later ones wait too, so they stay in order."""
        for index, (topic, data) in enumerate(records):
            try:
                payload = parse_payload(data)
            except PayloadError:
                continue
            parsed = self.topics.parse(topic)
            device = self.devices.get(parsed.device or "") if parsed else None
            if device is None:  # buffered by a run with other robots or ids
                self.buffer.records_dropped += 1
                continue
            if not device.born or device.device_name in waiting:
                waiting.add(device.device_name)
                deferred.append((topic, data))
                continue
            self._as_historical(payload, device)
            # Not published: paho already knows the connection is gone (this loop is told
            # next); the record stays for the next connection.
            if not self.active or not self._publish(topic, payload, device):
                self.buffer.put_back(path, deferred + records[index:])
                return False
            self.replayed += 1
            if index % REPLAY_BATCH == REPLAY_BATCH - 1:
                try:
                    await asyncio.sleep(0.01)  # let paho's thread drain its queue
                except asyncio.CancelledError:  # the service stops: keep what did not go out
                    self.buffer.put_back(path, deferred + records[index + 1 :])
                    raise
        if deferred:
            self.buffer.put_back(path, deferred)
        else:
            self.buffer.finish(path)
        return True

    @staticmethod
    def _as_historical(payload: Payload, device: Device) -> None:
        """A buffered DDATA as it goes out now (Sparkplug 3.0, "Payloads"): the payload's
        timestamp is when it is published, each metric keeps the time its value was captured
        and is marked historical, and carries no datatype (a DDATA's metrics should not;
        buffers written by older versions have it)."""
        payload.timestamp = now_ms()
        for metric in payload.metrics:
            # The robot's place in the settings may have changed since.
            metric.alias = device.alias_base + metric.alias % ALIAS_STRIDE
            metric.is_historical = True
            metric.ClearField("datatype")
