"""The load of ``bench/plant``: simulated cells publishing as our edge node does.

First a recording of the real thing (``record_template``): one emulated robot, the service with
its Sparkplug edge node on a local Mosquitto, a subscriber keeping the NBIRTH, the robot's
DBIRTH and every DDATA for a while, with when each came. That is the template: the edge node's
own metrics, aliases, data types, report-by-exception deadbands and rate (at most 10 DDATA/s per
robot), as they are, not a guess.

Then ``LoadGenerator``: ``cells`` simulated edge nodes (each its own MQTT connection, its will
the NDEATH with its bdSeq, spread over groups of ten: the plant's areas), each with ``robots``
devices that replay the template's DDATA at its times, each robot from its own point of it (so
the messages spread over time as a plant's do). Every message is built afresh with the edge
node's encoder (``sparkplug.payload``: ``make_payload``, ``add_metric``), the node's seq running
on, the payload's and the metrics' timestamps the moment it is built (the plant's hook measures
from the payload's). A Rebirth NCMD is answered as the edge node answers it: NBIRTH (seq 0, the
same bdSeq) and every DBIRTH, before the next DDATA.
"""

from __future__ import annotations

import heapq
import random
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from service_bench_support import _wait, emulated_cell, stop_process

from cobot_hmi.sparkplug.catalogue import ALIAS_STRIDE, BD_SEQ, REBIRTH
from cobot_hmi.sparkplug.payload import (
    DataType,
    MetricValue,
    Payload,
    add_metric,
    make_payload,
    metric_value,
    parse_payload,
)

NAMESPACE: Final = "spBv1.0"
CAL_GROUP, CAL_NODE = "bench-cal", "cal"
CELLS_PER_GROUP: Final = 10

Reported = tuple[int, DataType, MetricValue | None, bool]
"""One metric of a DDATA: (alias offset in its device, data type, value, historical)."""


@dataclass
class Template:
    """What one real robot's edge node published (module docstring)."""

    node_metrics: list[Payload.Metric]
    device_metrics: list[Payload.Metric]
    alias_base: int
    messages: list[tuple[float, list[Reported]]]
    """Each DDATA: (seconds after the first, its metrics)."""
    seconds: float

    @property
    def rate_hz(self) -> float:
        return len(self.messages) / self.seconds

    @property
    def metrics_per_message(self) -> float:
        return sum(len(m) for _, m in self.messages) / max(len(self.messages), 1)


@dataclass
class _Recording:
    births: dict[str, Payload] = field(default_factory=dict)
    data: list[tuple[float, Payload]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def on_message(self, _c: mqtt.Client, _u: object, message: mqtt.MQTTMessage) -> None:
        received = time.monotonic()
        kind = message.topic.split("/")[2]
        payload = parse_payload(bytes(message.payload))
        with self.lock:
            if kind in ("NBIRTH", "DBIRTH"):
                self.births[kind] = payload
            elif kind == "DDATA" and "DBIRTH" in self.births:
                self.data.append((received, payload))


def record_template(seconds: float, rpi_ms: float, broker_host: str, broker_port: int) -> Template:
    """``seconds`` of one emulated robot's DDATA from the service's own edge node."""
    recording = _Recording()
    client = mqtt.Client(CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv311)
    client.on_message = recording.on_message
    client.on_connect = lambda c, *_: c.subscribe(f"{NAMESPACE}/{CAL_GROUP}/#", qos=0)
    client.connect(broker_host, broker_port)
    client.loop_start()
    try:
        with (
            tempfile.TemporaryDirectory(prefix="cobot-bench-plant-cal-") as directory,
            emulated_cell(1, Path(directory)) as cell,
        ):
            url = f"mqtt://{broker_host}:{broker_port}"
            extra = (
                "--mqtt-url",
                url,
                "--sparkplug-group",
                CAL_GROUP,
                "--sparkplug-node",
                CAL_NODE,
            )
            service, _ = cell.serve(rpi_ms, *extra, log="service.log")
            try:
                _wait(lambda: len(recording.data) > 0, "calibration DDATA", service, 120)
                time.sleep(seconds)
            finally:
                stop_process(service, 20)
    finally:
        client.disconnect()
        client.loop_stop()
    with recording.lock:
        return _template(recording.births, list(recording.data))


def _template(births: dict[str, Payload], data: list[tuple[float, Payload]]) -> Template:
    device = births["DBIRTH"]
    types = {m.alias: DataType(m.datatype) for m in device.metrics}
    base = min(types) - min(types) % ALIAS_STRIDE
    first = data[0][0]
    messages = [
        (
            at - first,
            [
                (m.alias - base, types[m.alias], metric_value(m), m.is_historical)
                for m in payload.metrics
                if m.alias in types
            ],
        )
        for at, payload in data
    ]
    seconds = (data[-1][0] - first) + (data[-1][0] - first) / max(len(data) - 1, 1)
    return Template(list(births["NBIRTH"].metrics), list(device.metrics), base, messages, seconds)


# ---------------------------------------------------------------- the simulated cells


class SimCell:
    """One simulated edge node: its connection, seq, bdSeq and devices (module docstring)."""

    def __init__(self, index: int, robots: int, template: Template, host: str, port: int) -> None:
        self.group = f"area-{index // CELLS_PER_GROUP + 1:02d}"
        self.node = f"cell-{index + 1:03d}"
        self.devices = [f"r{r + 1:02d}" for r in range(robots)]
        self.template = template
        self.seq = 0
        self.bd_seq = 0
        self.births_wanted = threading.Event()
        self.rebirths_asked = 0
        self.births_sent = 0
        self.published = 0
        self.client = mqtt.Client(
            CallbackAPIVersion.VERSION2, client_id=f"bench-{self.node}", protocol=mqtt.MQTTv311
        )
        self.client.max_queued_messages_set(0)
        self.client.on_connect = self._on_connect
        self.client.on_message = self._on_message
        self._set_will()
        self.client.connect_async(host, port, keepalive=30)

    def topic(self, kind: str, device: str | None = None) -> str:
        tail = f"/{device}" if device is not None else ""
        return f"{NAMESPACE}/{self.group}/{kind}/{self.node}{tail}"

    def _set_will(self) -> None:
        death = make_payload(int(time.time() * 1000), None)
        add_metric(
            death,
            alias=None,
            name=BD_SEQ,
            timestamp_ms=death.timestamp,
            datatype=DataType.INT64,
            value=self.bd_seq,
        )
        self.client.will_set(self.topic("NDEATH"), death.SerializeToString(), qos=1)

    def _on_connect(self, client: mqtt.Client, *_: object) -> None:
        client.subscribe(self.topic("NCMD"), qos=0)
        self.births_wanted.set()

    def _on_message(self, _c: mqtt.Client, _u: object, message: mqtt.MQTTMessage) -> None:
        payload = parse_payload(bytes(message.payload))
        if any(m.name == REBIRTH and m.boolean_value for m in payload.metrics):
            self.rebirths_asked += 1
            self.births_wanted.set()

    def _next_seq(self) -> int:
        seq = self.seq
        self.seq = (self.seq + 1) % 256
        return seq

    def _publish(self, topic: str, payload: Payload) -> None:
        self.client.publish(topic, payload.SerializeToString(), qos=0)
        self.published += 1

    def births(self) -> None:
        """NBIRTH (seq 0) and every DBIRTH, the template's metrics with this node's aliases."""
        self.births_wanted.clear()
        now_ms = int(time.time() * 1000)
        self.seq = 0
        node = make_payload(now_ms, self._next_seq())
        for metric in self.template.node_metrics:
            copy = node.metrics.add()
            copy.CopyFrom(metric)
            copy.timestamp = now_ms
            if metric.name == BD_SEQ:
                copy.long_value = self.bd_seq
            elif metric.name == "Node Info/HMI URL":
                copy.string_value = f"http://{self.node}.plant.example:8000/"
        self._publish(self.topic("NBIRTH"), node)
        for number, device in enumerate(self.devices):
            payload = make_payload(now_ms, self._next_seq())
            for metric in self.template.device_metrics:
                copy = payload.metrics.add()
                copy.CopyFrom(metric)
                copy.alias = number * ALIAS_STRIDE + metric.alias - self.template.alias_base
                copy.timestamp = now_ms
            self._publish(self.topic("DBIRTH", device), payload)
        self.births_sent += 1

    def ddata(self, robot: int, metrics: list[Reported]) -> None:
        now_ms = int(time.time() * 1000)
        payload = make_payload(now_ms, self._next_seq())
        base = robot * ALIAS_STRIDE
        for offset, datatype, value, historical in metrics:
            metric = add_metric(
                payload,
                alias=base + offset,
                timestamp_ms=now_ms,
                datatype=datatype,
                value=value,
                with_datatype=False,
            )
            if historical:
                metric.is_historical = True
        self._publish(self.topic("DDATA", self.devices[robot]), payload)


class LoadGenerator:
    """``cells`` × ``robots`` replaying the template from one thread (module docstring)."""

    def __init__(
        self, cells: int, robots: int, template: Template, broker: tuple[str, int], seed: int = 1
    ) -> None:
        self.template = template
        self.cells = [SimCell(i, robots, template, *broker) for i in range(cells)]
        self.robots = robots
        self.random = random.Random(seed)
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self._run, name="plant load", daemon=True)
        self.lag_s: list[float] = []
        """How late each message went out (sampled: one in a hundred)."""
        self.sent = 0

    def start(self) -> None:
        for cell in self.cells:
            cell.client.loop_start()
        self.thread.start()

    def stop(self) -> None:
        self.stopping.set()
        self.thread.join(10)
        for cell in self.cells:
            cell.client.disconnect()
            cell.client.loop_stop()

    @property
    def rebirths_asked(self) -> int:
        return sum(c.rebirths_asked for c in self.cells)

    @property
    def births_sent(self) -> int:
        return sum(c.births_sent for c in self.cells)

    def _run(self) -> None:
        messages = self.template.messages
        start = time.monotonic() + 1.0
        queue: list[tuple[float, int, int, int]] = []
        for c in range(len(self.cells)):
            for r in range(self.robots):
                first = self.random.randrange(len(messages))
                queue.append((start + self.random.uniform(0, 0.1), c, r, first))
        heapq.heapify(queue)
        while not self.stopping.is_set():
            due, c, r, i = queue[0]
            wait = due - time.monotonic()
            if wait > 0:
                time.sleep(min(wait, 0.05))
                continue
            heapq.heappop(queue)
            cell = self.cells[c]
            if not cell.client.is_connected():
                heapq.heappush(queue, (due + 0.1, c, r, i))
                continue
            if cell.births_wanted.is_set():
                cell.births()
            cell.ddata(r, messages[i][1])
            self.sent += 1
            if self.sent % 100 == 0:
                self.lag_s.append(-wait)
            j = (i + 1) % len(messages)
            gap = messages[j][0] - messages[i][0] if j else self.template.seconds - messages[i][0]
            heapq.heappush(queue, (due + max(gap, 0.0), c, r, j))
