"""Layer: service (Sparkplug). The disk buffer replayed after a birth: the DDATA kept while the
broker was away, oldest first, published as historical, each after its robot's DBIRTH; one
replay at a time, what did not go out kept for the next.

A buffered DDATA names its metrics by alias only, and what an alias means depends on the
configuration (a robot's alarms are declared in its births, the cycle and health metrics after
them). A segment written with another catalogue than today's (``spool_catalogue``; another
``[[alarms]]`` configuration, another build) is replayed by name: each value goes out under
today's alias of the metric it was written for, and a value of a metric no longer declared (or
declared with another datatype) is dropped, never sent under an alias that now means another
metric. A segment written before segments carried their catalogue replays the layout's metrics
only (the buffer's directory is per layout version); one whose catalogue cannot be read is set
aside. The log says which.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Final

from cobot_hmi.sparkplug.buffer import CatalogueEntry, DiskBuffer, Segment, SpoolCatalogue
from cobot_hmi.sparkplug.catalogue import ALIAS_STRIDE
from cobot_hmi.sparkplug.node.core import Background, NodeStatus, Publisher
from cobot_hmi.sparkplug.node.device import Device, now_ms
from cobot_hmi.sparkplug.payload import Payload, PayloadError, parse_payload
from cobot_hmi.sparkplug.topics import Topics

log = logging.getLogger(__name__)

REPLAY_BATCH: Final = 50
"""Historical messages published between two yields of the web loop."""

Record = tuple[str, bytes]


def spool_catalogue(devices: Mapping[str, Device]) -> dict[str, list[CatalogueEntry]]:
    """Every robot's metrics as its births declare them (alias, name, datatype): what the
    aliases of the DDATA the buffer keeps today mean."""
    return {
        name: [
            (device.alias_base + m.offset, m.name, int(m.datatype))
            for m in (*device.catalogue.metrics, *device.events.metrics)
        ]
        for name, device in devices.items()
    }


class _Translation:
    """Today's offsets of the metrics a segment written with another catalogue names (by
    name and datatype), per robot; ``written_with`` ``None``: not known (the layout's metrics,
    numbered alike in every build of a layout version, are the only ones kept)."""

    def __init__(self, written_with: SpoolCatalogue | None, devices: Mapping[str, Device]) -> None:
        self.offsets: dict[str, dict[int, int]] = {}
        """Robot → offset when written → offset today."""
        self.dropped = 0
        """Values with no metric today (or of another datatype): not sent."""
        for name, device in devices.items():
            if written_with is None:
                self.offsets[name] = {m.offset: m.offset for m in device.catalogue.metrics}
                continue
            today = {
                (m.name, int(m.datatype)): m.offset
                for m in (*device.catalogue.metrics, *device.events.metrics)
            }
            self.offsets[name] = {
                alias % ALIAS_STRIDE: today[(metric, kind)]
                for alias, metric, kind in written_with.get(name, ())
                if (metric, kind) in today
            }

    def record(self, device: Device, data: bytes) -> bytes | None:
        """The record in today's aliases (``None``: none of its values has a metric today)."""
        payload = parse_payload(data)
        offsets = self.offsets.get(device.device_name, {})
        kept = []
        for metric in payload.metrics:
            offset = offsets.get(metric.alias % ALIAS_STRIDE) if metric.HasField("alias") else None
            if offset is None:
                self.dropped += 1
                continue
            metric.alias = device.alias_base + offset
            kept.append(metric)
        if not kept:
            return None
        del payload.metrics[:]
        payload.metrics.extend(kept)
        return payload.SerializeToString()


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
        segment = self.buffer.read_segment(path)
        records = segment.records
        if segment.unreadable:
            target = self.buffer.set_aside(path)
            log.error(
                "Sparkplug buffer: %s: its metric catalogue cannot be read; set aside as %s, "
                "not replayed (%d records)",
                path,
                target,
                len(records),
            )
            return True
        if not segment.current:
            records = self._translated(path, segment)
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

    def _translated(self, path: Path, segment: Segment) -> list[Record]:
        """A segment written with another catalogue, in today's aliases (see the module
        docstring); a record none of whose values has a metric today is dropped."""
        translation = _Translation(segment.catalogue, self.devices)
        records: list[Record] = []
        for topic, data in segment.records:
            parsed = self.topics.parse(topic)
            device = self.devices.get(parsed.device or "") if parsed else None
            if device is None:
                records.append((topic, data))  # dropped (and counted) by the replay
                continue
            try:
                translated = translation.record(device, data)
            except PayloadError:
                continue
            if translated is None:
                self.buffer.records_dropped += 1
            else:
                records.append((topic, translated))
        if segment.catalogue is None:
            how = "written before segments carried their metric catalogue: the layout's metrics"
        else:
            how = "written with another metric catalogue: replayed by name"
        log.warning(
            "Sparkplug buffer: %s (version %d) was %s under today's aliases; %d values of "
            "metrics not declared today (or of another datatype) dropped",
            path,
            segment.version,
            how,
            translation.dropped,
        )
        return records


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
