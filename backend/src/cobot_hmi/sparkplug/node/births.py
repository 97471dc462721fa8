"""Layer: service (Sparkplug). Births and deaths: NBIRTH (bdSeq, Rebirth, the layout
version, the cell's HMI address), each robot's DBIRTH (every metric with its properties, its
event metrics last) and DDEATH, the NDEATH payload (the MQTT will, and the clean leave); after
each DBIRTH the replayer sends the robot's history, and the alarm transitions a host asked for
again (or that came while the robot was offline) follow as historical.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Mapping
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.layout import LAYOUT_VERSION
from cobot_hmi.sparkplug.catalogue import BD_SEQ, REBIRTH, Catalogue, MetricDef, state_name
from cobot_hmi.sparkplug.catalogue import Role as MetricRole
from cobot_hmi.sparkplug.node.core import Publisher
from cobot_hmi.sparkplug.node.device import Device, now_ms
from cobot_hmi.sparkplug.node.replay import Replayer
from cobot_hmi.sparkplug.payload import (
    DataType,
    MetricValue,
    Property,
    add_metric,
    make_payload,
)
from cobot_hmi.sparkplug.topics import MessageType, Topics

LAYOUT_VERSION_METRIC: Final = "Node Info/Layout Version"
HMI_URL_METRIC: Final = "Node Info/HMI URL"
DEATH_WAIT_S: Final = 2.0
"""How long a clean leave waits for the broker to take its NDEATH."""


def death_payload(bd_seq: int) -> bytes:
    """The NDEATH: the bdSeq of the connection it ends (Sparkplug 3.0)."""
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


class BirthWriter:
    """NBIRTH, DBIRTH, DDEATH and the clean leave's NDEATH, through ``publisher``; a DBIRTH
    hands over to ``replayer``."""

    def __init__(
        self,
        topics: Topics,
        catalogue: Catalogue,
        devices: Mapping[str, Device],
        publisher: Publisher,
        replayer: Replayer,
        *,
        hmi_url: str = "",
    ) -> None:
        self.topics = topics
        self.catalogue = catalogue
        self.devices = devices
        self.publisher = publisher
        self.replayer = replayer
        self.hmi_url = hmi_url
        """The cell's HMI address, named in the NBIRTH (empty: not named)."""

    def birth_all(self, history_since_ms: int | None = None) -> None:
        """NBIRTH (seq 0), then a DBIRTH for every robot that is up; ``history_since_ms``: a
        host asked for the alarm transitions since then again (after each DBIRTH)."""
        payload = make_payload(now_ms(), self.publisher.session.birth_seq())
        now = now_ms()
        add_metric(
            payload,
            alias=None,
            name=BD_SEQ,
            timestamp_ms=now,
            datatype=DataType.INT64,
            value=self.publisher.bd_seq,
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
        if self.hmi_url:
            add_metric(
                payload,
                alias=None,
                name=HMI_URL_METRIC,
                timestamp_ms=now,
                datatype=DataType.STRING,
                value=self.hmi_url,
                properties=(Property("description", DataType.STRING, "the cell's HMI"),),
            )
        self.publisher.publish(self.topics.node_topic(MessageType.NBIRTH), payload, None)
        for device in self.devices.values():
            device.born = False
            if device.alive:
                self.device_birth(device, history_since_ms)

    def device_birth(self, device: Device, history_since_ms: int | None = None) -> None:
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
        events = device.events
        device.event_changes.clear()  # the birth carries their values
        for metric, event_value, event_stamp in zip(
            events.metrics, events.values, events.stamps, strict=True
        ):
            add_metric(
                payload,
                alias=device.alias_base + metric.offset,
                name=metric.name,
                timestamp_ms=event_stamp,
                datatype=metric.datatype,
                value=event_value,
                properties=self._birth_properties(metric, event_value),
            )
        self.publisher.publish(
            self.topics.device_topic(MessageType.DBIRTH, device.device_name), payload, device
        )
        device.born = True
        since = device.history_from_ms
        if history_since_ms is not None:
            since = history_since_ms if since is None else min(since, history_since_ms)
        device.history_from_ms = None
        if since is not None:
            self._alarm_history(device, since)
        self.replayer.after_birth()  # its history, if it has some, after its birth

    def _alarm_history(self, device: Device, since_ms: int) -> None:
        """The robot's alarm transitions since ``since_ms``, as historical (a host keeps each
        once: a transition it already had is not counted twice)."""
        transitions = device.events.transitions_since(since_ms)
        if not transitions:
            return
        payload = make_payload(now_ms(), None)
        for offset, value, stamp in transitions:
            metric = add_metric(
                payload,
                alias=device.alias_base + offset,
                timestamp_ms=stamp,
                datatype=DataType.BOOLEAN,
                value=value,
                with_datatype=False,
            )
            metric.is_historical = True
        self.publisher.publish(
            self.topics.device_topic(MessageType.DDATA, device.device_name), payload, device
        )

    def device_death(self, device: Device) -> None:
        payload = make_payload(now_ms(), None)
        self.publisher.publish(
            self.topics.device_topic(MessageType.DDEATH, device.device_name), payload, device
        )
        device.born = False

    async def leave(self) -> None:
        """A clean leave while connected: each born robot's DDEATH, then the NDEATH, waited
        for (at most ``DEATH_WAIT_S``) so that it reaches the broker before the disconnect."""
        for device in self.devices.values():
            if device.born:
                self.device_death(device)
        info = self.publisher.publish_death(
            self.topics.node_topic(MessageType.NDEATH), death_payload(self.publisher.bd_seq)
        )
        with contextlib.suppress(RuntimeError, ValueError):
            await asyncio.to_thread(info.wait_for_publish, DEATH_WAIT_S)

    @staticmethod
    def _birth_properties(metric: MetricDef, value: MetricValue | None) -> list[Property]:
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
