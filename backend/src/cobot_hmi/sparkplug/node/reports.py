"""Layer: service (Sparkplug). Each robot's reports on the web loop: a tick at most every
``period_s`` right after frames arrived; a DDEATH when its connection went, a DBIRTH when it
came (back), otherwise a DDATA with what changed (``rbe``), the O→T image, the control holder
and command outcomes, published when born, buffered on disk while the broker is away.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Iterable, Mapping
from typing import Final

from cobot_hmi.codec import CommandImage
from cobot_hmi.layout import O2T_FIELDS
from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.catalogue import Catalogue, has_state_names, state_name
from cobot_hmi.sparkplug.event_metrics import EventChange
from cobot_hmi.sparkplug.node.births import BirthWriter
from cobot_hmi.sparkplug.node.core import NodeStatus, Publisher
from cobot_hmi.sparkplug.node.device import Device, now_ms
from cobot_hmi.sparkplug.payload import (
    DataMetricWriter,
    DataType,
    MetricValue,
    Payload,
    Property,
    add_metric,
    data_metric_writer,
    make_payload,
)
from cobot_hmi.sparkplug.rbe import Change
from cobot_hmi.sparkplug.topics import MessageType, Topics

log = logging.getLogger(__name__)

_LIVE_DDATA: Final = MessageType.DDATA.value
"""How the publisher counts a DDATA of this loop (never historical)."""

Moved = tuple[list[float], list[int], int]
"""The analog values of a robot's newest frame, which of them moved (``Reporter.analog_moved``)
and the frame's time in ms."""


class DeviceReports:
    """The robots' ticks: one task for all of them (``start``, ``stop``), each robot's tick
    (``tick``) reporting through ``births`` and ``publisher``, or into ``buffer`` while not
    born."""

    def __init__(
        self,
        *,
        topics: Topics,
        catalogue: Catalogue,
        devices: Mapping[str, Device],
        births: BirthWriter,
        publisher: Publisher,
        buffer: DiskBuffer,
        status: NodeStatus,
        period_s: float,
    ) -> None:
        self.topics = topics
        self.catalogue = catalogue
        self.devices = devices
        self.births = births
        self.publisher = publisher
        self.buffer = buffer
        self.status = status
        self.period_s = period_s
        self._command_offsets = {
            f.name: next(m.offset for m in catalogue.command_metrics if m.field == f.name)
            for f in O2T_FIELDS
        }
        self._writers: list[DataMetricWriter | None] = [
            None if has_state_names(m) else data_metric_writer(m.datatype)
            for m in catalogue.metrics
        ]
        """How a DDATA carries each catalogue metric (by offset); ``None``: with the name of
        its value (``_add_change``)."""
        # ``_report`` appends the analog values as Float metrics without names itself.
        assert all(
            self._writers[span.first + i] is data_metric_writer(DataType.FLOAT)
            for span in catalogue.analog_spans
            for i in range(span.count)
        )
        self._ddata_topics: dict[str, str] = {}
        """Each robot's DDATA topic, made once."""
        self._tasks: list[asyncio.Task[None]] = []
        self.tick_seconds = 0.0
        """CPU time of the robots' ticks on the web loop (reports, encoding, publishing calls):
        the thread's own, so a busy machine's preemptions do not count."""

    def start(self) -> None:
        """The robots' ticks: one task on the running loop for all of them."""
        self._tasks.append(asyncio.create_task(self._devices_loop(), name="sparkplug reports"))

    async def stop(self) -> None:
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks.clear()

    async def _devices_loop(self) -> None:
        """Each robot's tick at most every ``period_s``, each right after a frame of the robot
        arrived: the newest frame is then at its freshest when reported (one wake-up per round
        from the cyclic thread, the devices' ``on_frames``). One task for every robot: a round
        ticks the robots that are due, with one sleep and one reading of the thread's CPU clock
        for the whole cell (a task per robot made two clock readings per robot and tick, a
        system call that takes the scheduler's lock: a quarter of the edge node's time on the
        web loop at 8 robots, py-spy)."""
        loop = asyncio.get_running_loop()
        devices = list(self.devices.values())
        period = self.period_s
        # When each is due: max(its last tick, its last DDATA) + period, as each is ticked.
        due = dict.fromkeys(devices, loop.time() + period)
        while True:
            await asyncio.sleep(max(0.0, min(due.values(), default=math.inf) - loop.time()))
            now = loop.time()
            ready = [d for d in devices if due[d] <= now]
            await self._frames_of(d for d in ready if d.robot.connection.down_since is None)
            started = time.thread_time()
            for device in ready:
                ticked = loop.time()
                try:
                    self.tick(device)
                except Exception:  # a bug here must not end the robot's reports for good
                    log.exception("Sparkplug tick of %s failed", device.device_name)
                due[device] = max(ticked, device.reported_at) + period
            self.tick_seconds += time.thread_time() - started

    async def _frames_of(self, devices: Iterable[Device]) -> None:
        """Until a frame of each of ``devices`` arrived after this call, or ``period_s``."""
        waiting = list(devices)
        for device in waiting:
            device.arrived.clear()
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(self.period_s):
                for device in waiting:
                    if not device.arrived.is_set():
                        await device.arrived.wait()

    def tick(self, device: Device) -> None:
        """What changed of ``device`` since its last tick, reported."""
        robot = device.robot
        items = device.take()
        connected = robot.connection.down_since is None
        if device.alive and (not connected or robot.connection.connects != device.connects_seen):
            device.alive = False
            if device.born and self.status.active:
                self.births.device_death(device)
                # What its alarms do while it is offline follows its next DBIRTH.
                device.history_from_ms = now_ms()
            device.born = False
        if not connected:
            return
        if items:
            device.frame = (items[-1][2], items[-1][1])
        if not device.alive:
            if not items:
                return  # no frame of this connection yet
            device.connects_seen = robot.connection.connects
            device.alive = True
            device.reporter.baseline(items[-1][2])
            self._read_status(device)
            if self.status.active:
                self.births.device_birth(device)
            return
        changes: list[EventChange] = list(device.reporter.discrete_changes(items))
        analog: Moved | None = None
        if items:
            newest = items[-1]
            values, moved_at = device.reporter.analog_moved(newest[2])
            if moved_at:
                analog = (values, moved_at, int(newest[1] * 1000))
        later: list[EventChange] = [*self._status_changes(device), *device.take_event_changes()]
        if changes or analog or later:
            self._report(device, changes, analog, later)

    def _read_status(self, device: Device) -> None:
        # A try costs nothing unless it raises (``contextlib.suppress`` made a context a tick).
        command: CommandImage | None
        try:
            command = device.robot.link.command
        except AssertionError:  # no originator yet
            command = device.command
        device.command = command
        holder = device.robot.control.holder
        device.holder = holder.user if holder is not None else ""

    def _status_changes(self, device: Device) -> list[Change]:
        """The O→T image, the control holder and command outcomes, when they changed."""
        now = now_ms()
        changes: list[Change] = []
        before = device.command
        holder_before = device.holder
        self._read_status(device)
        command = device.command
        if command is not None and before is not None and command != before:
            for f in O2T_FIELDS:
                new, old = getattr(command, f.name), getattr(before, f.name)
                if new != old:
                    first = self._command_offsets[f.name]
                    changes.extend(
                        (first + i, a, now)
                        for i, (a, b) in enumerate(zip(new, old, strict=True))
                        if a != b
                    )
        if device.holder != holder_before:
            changes.append((self.catalogue.control_holder.offset, device.holder, now))
        if device.outcome_pending:
            device.outcome_pending = False
            outcome, reason = device.outcome
            changes.append((self.catalogue.write_outcome.offset, outcome, now))
            changes.append((self.catalogue.write_reason.offset, reason, now))
        return changes

    def _report(
        self,
        device: Device,
        changes: list[EventChange],
        analog: Moved | None,
        later: list[EventChange],
    ) -> None:
        """A DDATA (the discrete ``changes``, the ``analog`` values that moved, the ``later``
        changes, in this order): published when born, buffered on disk while the broker is
        away."""
        # The payload's time and the rate's reference are one instant.
        device.reported_at = asyncio.get_running_loop().time()
        payload = make_payload(now_ms(), None)
        if changes:
            self._add_changes(payload, device, changes)
        if analog is not None:
            # Analog metrics are Float without names (the catalogue's, checked when made):
            # appended here as ``add_metric`` would, each field set on the new metric (a fifth
            # faster with upb than ``add`` with keywords: ~100 metrics a DDATA, 320 a second at
            # 32 robots).
            values, moved_at, stamp = analog
            add = payload.metrics.add
            base = device.alias_base
            offsets = device.reporter.analog_offsets
            for i in moved_at:
                metric = add()
                metric.alias = base + offsets[i]
                metric.timestamp = stamp
                metric.float_value = values[i]
        if later:
            self._add_changes(payload, device, later)
        topic = self._ddata_topics.get(device.device_name)
        if topic is None:
            topic = self.topics.device_topic(MessageType.DDATA, device.device_name)
            self._ddata_topics[device.device_name] = topic
        if self.status.active and device.born:
            if self.publisher.publish(topic, payload, device, _LIVE_DDATA):
                return
            # paho knows the connection is gone and this loop is told next: keep it.
            payload.ClearField("seq")
        elif self.status.active:
            return  # not born on this connection yet: its DBIRTH will carry the values
        if self.buffer.append(topic, payload.SerializeToString()):
            device.messages["DDATA_buffered"] += 1

    def _add_changes(self, payload: Payload, device: Device, changes: list[EventChange]) -> None:
        metrics = payload.metrics
        writers = self._writers
        known = len(writers)
        base = device.alias_base
        for offset, value, stamp in changes:
            write = writers[offset] if offset < known else None
            if write is not None and value is not None:
                write(metrics, base + offset, stamp, value)
            else:
                self._add_change(payload, device, offset, value, stamp)

    @staticmethod
    def _add_change(
        payload: Payload, device: Device, offset: int, value: MetricValue | None, stamp: int
    ) -> None:
        """A change of an event metric, a coded one (a ``name`` property with the value's
        name) or to Null, as the metric's definition says."""
        metric = device.metric(offset)
        name = state_name(metric, value)
        add_metric(
            payload,
            alias=device.alias_base + offset,
            timestamp_ms=stamp,
            datatype=metric.datatype,
            value=value,
            properties=(Property("name", DataType.STRING, name),) if name else (),
            with_datatype=False,  # the DBIRTH gave it (Sparkplug 3.0: not in DATA)
        )
