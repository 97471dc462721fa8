"""Layer: service (Sparkplug). The disk buffer replayed after a birth: the DDATA kept while the
broker was away, oldest first, published as historical, each after its robot's DBIRTH; one
replay at a time, what did not go out kept for the next.
"""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from pathlib import Path
from typing import Final

from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.catalogue import ALIAS_STRIDE
from cobot_hmi.sparkplug.node.core import Background, NodeStatus, Publisher
from cobot_hmi.sparkplug.node.device import Device, now_ms
from cobot_hmi.sparkplug.payload import Payload, PayloadError, parse_payload
from cobot_hmi.sparkplug.topics import Topics

REPLAY_BATCH: Final = 50
"""Historical messages published between two yields of the web loop."""


class Replayer:
    """Replays ``buffer`` through ``publisher`` while the node is born (``status.active``),
    on a task of ``background``; ``after_birth`` after each DBIRTH."""

    def __init__(
        self,
        *,
        topics: Topics,
        devices: Mapping[str, Device],
        buffer: DiskBuffer,
        publisher: Publisher,
        status: NodeStatus,
        background: Background,
    ) -> None:
        self.topics = topics
        self.devices = devices
        self.buffer = buffer
        self.publisher = publisher
        self.status = status
        self.background = background
        self.replayed = 0
        """Buffered DDATA published as historical (``/metrics``)."""
        self.running = False
        """A replay is under way (set by whoever starts it)."""
        self._again = False

    def after_birth(self) -> None:
        """A robot was born: its history, if the buffer has some, goes out now."""
        if not self.buffer.records_buffered:
            return
        self._again = True
        if not self.running:
            # Marked here, not when the task first runs: the next robot's DBIRTH, in the same
            # turn of the loop, must find it running (one replay, not one per birth).
            self.running = True
            self.background.spawn(self._replay(), "sparkplug replay")

    async def _replay(self) -> None:
        """The buffered DDATA, oldest first, marked historical, each after its robot's DBIRTH
        (a robot not born yet keeps its records for a replay after its birth). One at a time:
        ``running`` is set by whoever spawns it; a birth meanwhile asks for another pass."""
        try:
            self._again = True
            while self._again and self.status.active:
                self._again = False
                for path in self.buffer.sealed():
                    if not await self._replay_segment(path):
                        return
        finally:
            self.running = False

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
            as_historical(payload, device)
            # Not published: paho already knows the connection is gone (this loop is told
            # next); the record stays for the next connection.
            if not self.status.active or not self.publisher.publish(topic, payload, device):
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


def as_historical(payload: Payload, device: Device) -> None:
    """A buffered DDATA as it goes out now (Sparkplug 3.0, "Payloads"): the payload's timestamp
    is when it is published, each metric keeps the time its value was captured and is marked
    historical, and carries no datatype (a DDATA's metrics should not; buffers written by older
    versions have it)."""
    payload.timestamp = now_ms()
    for metric in payload.metrics:
        # The robot's place in the settings may have changed since.
        metric.alias = device.alias_base + metric.alias % ALIAS_STRIDE
        metric.is_historical = True
        metric.ClearField("datatype")
