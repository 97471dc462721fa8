"""The Sparkplug spool keeps the metric catalogue it was written with, and a replay after a
restart under another configuration never sends a value under an alias that now means another
metric (``sparkplug/buffer.py``, ``sparkplug/node/replay.py``).

A robot's alarms are declared in its births (``Alarm/<key>/…``), the cycle and health metrics
after them, so their aliases move with the ``[[alarms]]`` configuration. Each scenario writes a
spool as one run of the edge node would, then starts the next run's parts (its devices, buffer,
births and replayer) with other alarms, against a real Mosquitto read by an independent
subscriber that decodes every payload (``mosquitto_support``): each replayed value must arrive
under the alias today's DBIRTH gives the metric it was written for.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import AsyncIterator, Iterator
from contextlib import asynccontextmanager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import paho.mqtt.client as mqtt
import pytest

from cobot_hmi.emulator.static_robot import standing_frame
from cobot_hmi.sparkplug.buffer import SET_ASIDE, DiskBuffer
from cobot_hmi.sparkplug.catalogue import Catalogue
from cobot_hmi.sparkplug.event_metrics import AlarmDeclaration
from cobot_hmi.sparkplug.mqtt_client import BrokerAddress, ClientOptions, make_client
from cobot_hmi.sparkplug.node.births import BirthWriter
from cobot_hmi.sparkplug.node.core import Background, NodeStatus, Publisher
from cobot_hmi.sparkplug.node.device import Device
from cobot_hmi.sparkplug.node.replay import Replayer, spool_catalogue
from cobot_hmi.sparkplug.payload import DataType, MetricValue, add_metric, make_payload
from cobot_hmi.sparkplug.session import NodeSession
from cobot_hmi.sparkplug.topics import MessageType, Topics
from mosquitto_support import Message, Subscriber, mosquitto, needs_mosquitto
from sparkplug_parts_support import device_of
from waiting import eventually

if TYPE_CHECKING:
    pass

pytestmark = [needs_mosquitto, pytest.mark.timeout(120)]

ROBOT = "m1013"
TOPICS = Topics("cell", "edge")
"""As the version 2 fixture's records name them."""
DDATA = TOPICS.device_topic(MessageType.DDATA, ROBOT)
LEGACY_V2 = Path(__file__).parent / "legacy" / "stored_formats" / "v2" / "sparkplug-spool"
STAMP_MS = 1_764_547_200_000
LAYOUT_METRIC = "controlbox_di/DI 6"
"""A metric of the layout (offset 5 in every configuration)."""


def alarm(key: str, priority: str = "medium") -> AlarmDeclaration:
    return AlarmDeclaration(key=key, text=key, priority=priority, active=False, changed_ms=None)


BEFORE = [alarm("door_open"), alarm("over_temp", "high")]
AFTER = [alarm("estop", "critical"), alarm("power_loss"), alarm("over_temp", "high")]
"""``door_open`` went, two came first: ``over_temp`` and everything after it moved, so the
aliases written for ``over_temp`` and ``Cycle/Last`` now mean ``power_loss`` and ``over_temp``."""


def device(alarms: list[AlarmDeclaration], number: int) -> Device:
    return device_of(ROBOT, Catalogue({}), number, alarms)


WRITTEN: dict[str, tuple[DataType, MetricValue]] = {
    LAYOUT_METRIC: (DataType.BOOLEAN, True),
    "Alarm/over_temp/Active": (DataType.BOOLEAN, True),
    "Alarm/over_temp/Priority": (DataType.STRING, "high"),
    "Alarm/door_open/Active": (DataType.BOOLEAN, True),
    "Cycle/Last": (DataType.DOUBLE, 12.5),
    "Health/J1/Life Used": (DataType.DOUBLE, 3.25),
}
"""What the first run buffered, by name (``door_open`` has no metric in the second)."""


def write_spool(directory: Path, written_by: Device, records: int) -> None:
    """DDATA as the first run's reports buffer them: by alias only, no datatype."""
    buffer = DiskBuffer(directory, 1 << 20, spool_catalogue({ROBOT: written_by}))
    offsets = {
        m.name: m.offset for m in (*written_by.catalogue.metrics, *written_by.events.metrics)
    }
    for i in range(records):
        payload = make_payload(STAMP_MS + i, None)
        for name, (datatype, value) in WRITTEN.items():
            add_metric(
                payload,
                alias=written_by.alias_base + offsets[name],
                timestamp_ms=STAMP_MS + i,
                datatype=datatype,
                value=value,
                with_datatype=False,
            )
        assert buffer.append(DDATA, payload.SerializeToString())


@contextmanager
def connected_client(url: str) -> Iterator[mqtt.Client]:
    address = BrokerAddress.parse(url)
    client = make_client(ClientOptions(address, "spool-node", "", "", None, None, None))
    client.connect(address.host, address.port, 30)
    client.loop_start()
    try:
        yield client
    finally:
        client.disconnect()
        client.loop_stop()


@dataclass
class NextRun:
    """The second run's parts, born, its buffer replayed; what the broker showed."""

    device: Device
    buffer: DiskBuffer
    replayer: Replayer
    birth: Message
    replayed: list[Message]


@asynccontextmanager
async def next_run(
    tmp_path: Path, host: str, spool: Path, alarms: list[Any]
) -> AsyncIterator[NextRun]:
    """The edge node restarted with ``alarms`` (the robot now the settings' first): its parts
    built on the spool, the robot born; until the buffer went out."""
    async with mosquitto(host, tmp_path) as broker, Subscriber(broker) as subscriber:
        with connected_client(broker.url) as client:
            await eventually(client.is_connected)
            publisher = Publisher(NodeSession(tmp_path / "bdseq"))
            publisher.client = client
            robot = device(alarms, number=1)
            robot.frame = (standing_frame(), time.time())
            robot.alive = True
            devices = {ROBOT: robot}
            buffer = DiskBuffer(spool, 1 << 20, spool_catalogue(devices))
            replayer = Replayer(
                topics=TOPICS,
                devices=devices,
                buffer=buffer,
                publisher=publisher,
                status=NodeStatus(active=True),
                background=Background(),
            )
            BirthWriter(TOPICS, robot.catalogue, devices, publisher, replayer).birth_all()
            await eventually(lambda: not replayer.running and not buffer.records_buffered)
            await subscriber.wait_for(lambda ms: any(m.kind == "DBIRTH" for m in ms))
            [birth] = subscriber.of("DBIRTH", ROBOT)
            expected = replayer.replayed
            await subscriber.wait_for(lambda ms: len(subscriber.of("DDATA", ROBOT)) >= expected)
            yield NextRun(robot, buffer, replayer, birth, subscriber.of("DDATA", ROBOT))
            await replayer.background.cancel()


def replayed_by_name(run: NextRun) -> list[dict[str, object]]:
    """Each replayed DDATA's values by the name today's DBIRTH gives their aliases (every
    alias must be one it declared)."""
    names = {m.alias: m.name for m in run.birth.metrics}
    out = []
    for message in run.replayed:
        assert all(m.is_historical for m in message.metrics)
        assert {m.alias for m in message.metrics} <= names.keys(), "an alias not born"
        out.append({str(names[m.alias]): m.value for m in message.metrics})
    return out


async def test_a_spool_of_another_alarm_configuration_replays_by_name(
    tmp_path: Path, plc_host: str, caplog: pytest.LogCaptureFixture
) -> None:
    spool = tmp_path / "spool"
    written_by = device(BEFORE, number=2)
    write_spool(spool, written_by, records=3)
    moved = written_by.events.alarm_offsets["over_temp"]
    with caplog.at_level("WARNING", logger="cobot_hmi.sparkplug.node.replay"):
        async with next_run(tmp_path, plc_host, spool, AFTER) as run:
            assert run.device.events.alarm_offsets["over_temp"] != moved
            assert run.replayer.replayed == 3 and run.buffer.records_buffered == 0
            expected = {name: value for name, (_, value) in WRITTEN.items() if "door" not in name}
            assert replayed_by_name(run) == [expected] * 3
            assert [m.metrics[0].timestamp for m in run.replayed] == [
                STAMP_MS + i for i in range(3)
            ]
    assert "written with another metric catalogue: replayed by name" in caplog.text
    assert "3 values of metrics not declared today" in caplog.text  # door_open's, once a record


async def test_a_spool_of_the_same_configuration_replays_as_it_was(
    tmp_path: Path, plc_host: str, caplog: pytest.LogCaptureFixture
) -> None:
    spool = tmp_path / "spool"
    write_spool(spool, device(BEFORE, number=1), records=2)
    with caplog.at_level("WARNING", logger="cobot_hmi.sparkplug.node.replay"):
        async with next_run(tmp_path, plc_host, spool, BEFORE) as run:
            assert replayed_by_name(run) == [{n: v for n, (_, v) in WRITTEN.items()}] * 2
    assert "metric catalogue" not in caplog.text


async def test_a_spool_of_the_previous_version_replays_the_layouts_metrics_only(
    tmp_path: Path, plc_host: str, caplog: pytest.LogCaptureFixture
) -> None:
    """Version 2 (``legacy/stored_formats/v2``): each record holds ``controlbox_di/DI 6`` and
    the first event metric of a robot with no alarms then (``Cycle/Last``); its catalogue is not
    known, so only the layout's metric goes out."""
    spool = tmp_path / "spool"
    shutil.copytree(LEGACY_V2, spool)
    with caplog.at_level("WARNING", logger="cobot_hmi.sparkplug.node.replay"):
        async with next_run(tmp_path, plc_host, spool, AFTER) as run:
            assert replayed_by_name(run) == [
                {LAYOUT_METRIC: True},
                {LAYOUT_METRIC: False},
                {LAYOUT_METRIC: True},
            ]
    assert "written before segments carried their metric catalogue" in caplog.text
    assert "3 values of metrics not declared today" in caplog.text


async def test_a_spool_whose_catalogue_cannot_be_read_is_set_aside(
    tmp_path: Path, plc_host: str, caplog: pytest.LogCaptureFixture
) -> None:
    spool = tmp_path / "spool"
    write_spool(spool, device(BEFORE, number=1), records=2)
    [segment] = spool.glob("*.seg")
    data = bytearray(segment.read_bytes())
    data[10] ^= 0xFF  # the catalogue's fingerprint: it no longer matches the catalogue
    segment.write_bytes(bytes(data))
    with caplog.at_level("ERROR", logger="cobot_hmi.sparkplug.node.replay"):
        async with next_run(tmp_path, plc_host, spool, BEFORE) as run:
            assert run.replayed == [] and run.replayer.replayed == 0
            assert run.buffer.records_set_aside == 2
    assert (spool / SET_ASIDE / segment.name).read_bytes() == bytes(data)
    assert not segment.exists()
    assert "its metric catalogue cannot be read; set aside" in caplog.text
