"""The edge node's parts (``sparkplug.node``), each built alone with what it needs: the
``Publisher``, the ``BirthWriter``, the ``Replayer``, the ``DeviceReports``, the
``CommandHandler``, the ``PrimaryHost`` and the ``NodeConnection`` against a real Mosquitto
read by an independent subscriber (``mosquitto_support``), the ``NodeMetrics`` view on its own.
A robot is a stand-in with the few things a device reads of it (no emulator, no service).
"""

from __future__ import annotations

import time
from collections.abc import AsyncIterator, Iterator
from contextlib import asynccontextmanager, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast

import orjson
import paho.mqtt.client as mqtt
import pytest

from cobot_hmi.codec import Frame
from cobot_hmi.emulator.static_robot import standing_frame
from cobot_hmi.service.robots.frame_notifier import FrameRecord
from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.catalogue import ALIAS_STRIDE, BD_SEQ, Catalogue
from cobot_hmi.sparkplug.mqtt_client import BrokerAddress, ClientOptions, make_client
from cobot_hmi.sparkplug.node.births import BirthWriter
from cobot_hmi.sparkplug.node.command_handling import CommandHandler, door_writer
from cobot_hmi.sparkplug.node.connection import NodeConnection, PrimaryHost
from cobot_hmi.sparkplug.node.core import Background, NodeStatus, Publisher
from cobot_hmi.sparkplug.node.device import Device, now_ms
from cobot_hmi.sparkplug.node.metrics import NodeMetrics
from cobot_hmi.sparkplug.node.replay import Replayer
from cobot_hmi.sparkplug.node.reports import DeviceReports
from cobot_hmi.sparkplug.payload import DataType, add_metric, make_payload
from cobot_hmi.sparkplug.session import NodeSession
from cobot_hmi.sparkplug.topics import MessageType, Topics
from mosquitto_support import Broker, Subscriber, encode_command, mosquitto, needs_mosquitto
from sparkplug_parts_support import StandInRobot, device_of, report_parts
from sparkplug_support import BOOLEAN
from waiting import eventually

if TYPE_CHECKING:
    pass

pytestmark = [needs_mosquitto, pytest.mark.timeout(120)]

GROUP, NODE = "plant", "parts"


def feed(device: Device, frame: Frame) -> None:
    """A frame as the robot's notifier hands it to its consumers."""
    device.on_frames(device.device_name, [FrameRecord(1, time.time(), frame, 1, b"")])


def di_changed(frame: Frame) -> Frame:
    """``frame`` with the control box's first digital input the other way round."""
    di = list(frame.controlbox_di)
    di[0] = not di[0]
    return frame._replace(controlbox_di=tuple(di))


@dataclass
class Wired:
    """A broker, a subscriber reading it, and a ``Publisher`` on a connected client."""

    broker: Broker
    subscriber: Subscriber
    publisher: Publisher
    topics: Topics
    catalogue: Catalogue


@contextmanager
def connected_client(broker: Broker) -> Iterator[mqtt.Client]:
    address = BrokerAddress.parse(broker.url)
    client = make_client(ClientOptions(address, "parts-node", "", "", None, None, None))
    client.connect(address.host, address.port, 30)
    client.loop_start()
    try:
        yield client
    finally:
        client.disconnect()
        client.loop_stop()


@asynccontextmanager
async def wired(tmp_path: Path, host: str) -> AsyncIterator[Wired]:
    async with mosquitto(host, tmp_path) as broker, Subscriber(broker) as subscriber:
        publisher = Publisher(NodeSession(tmp_path / "bdseq"))
        with connected_client(broker) as client:
            await eventually(client.is_connected)
            publisher.client = client
            yield Wired(broker, subscriber, publisher, Topics(GROUP, NODE), Catalogue({}))


def replayer_of(w: Wired, devices: dict[str, Device], buffer: DiskBuffer) -> Replayer:
    return Replayer(
        topics=w.topics,
        devices=devices,
        buffer=buffer,
        publisher=w.publisher,
        status=NodeStatus(active=True),
        background=Background(),
    )


async def test_publisher_numbers_publishes_and_counts(tmp_path: Path, plc_host: str) -> None:
    async with wired(tmp_path, plc_host) as w:
        publisher, topics = w.publisher, w.topics
        device = device_of("m1013", w.catalogue)
        assert publisher.bd_seq == publisher.session.bd_seq == 0
        publisher.publish(topics.node_topic(MessageType.NBIRTH), make_payload(now_ms(), 0), None)
        publisher.session.birth_seq()
        ddata = topics.device_topic(MessageType.DDATA, "m1013")
        assert publisher.publish(ddata, make_payload(now_ms(), None), device)
        historical = make_payload(now_ms(), None)
        add_metric(historical, alias=1, timestamp_ms=1, datatype=DataType.BOOLEAN, value=True)
        historical.metrics[0].is_historical = True
        assert publisher.publish(ddata, historical, device)
        publisher.publish_death(topics.node_topic(MessageType.NDEATH), b"")
        await w.subscriber.wait_for(lambda ms: len(ms) == 4)
        assert [(m.kind, m.seq) for m in w.subscriber.snapshot()] == [
            ("NBIRTH", 0),
            ("DDATA", 1),
            ("DDATA", 2),
            ("NDEATH", None),
        ]
        assert publisher.node_messages == {"NBIRTH": 1, "NDEATH": 1}
        assert device.messages == {"DDATA": 1, "DDATA_historical": 1}
        assert device.bytes["DDATA"] > 0
        # A client with no connection takes nothing: not sent, not counted.
        publisher.client = make_client(
            ClientOptions(BrokerAddress.parse(w.broker.url), "idle", "", "", None, None, None)
        )
        assert not publisher.publish(ddata, make_payload(now_ms(), None), device)
        assert device.messages["DDATA"] == 1


async def test_birth_writer_births_and_leaves(tmp_path: Path, plc_host: str) -> None:
    async with wired(tmp_path, plc_host) as w:
        device = device_of("m1013", w.catalogue, number=2)
        device.frame = (standing_frame(), time.time())
        device.alive = True
        devices = {"m1013": device}
        replayer = replayer_of(w, devices, DiskBuffer(tmp_path / "buffer", 1 << 20))
        births = BirthWriter(w.topics, w.catalogue, devices, w.publisher, replayer)
        births.birth_all()
        await w.subscriber.wait_for(lambda ms: len(ms) == 2)
        nbirth, dbirth = w.subscriber.snapshot()
        assert (nbirth.kind, nbirth.seq, dbirth.kind, dbirth.seq) == ("NBIRTH", 0, "DBIRTH", 1)
        assert {m.name: m.value for m in nbirth.metrics}[BD_SEQ] == w.publisher.bd_seq
        # The catalogue's metrics, then the robot's event metrics (alarms, cycles, health).
        assert [m.alias for m in dbirth.metrics] == [
            2 * ALIAS_STRIDE + m.offset for m in (*w.catalogue.metrics, *device.events.metrics)
        ]
        assert device.born
        await births.leave()
        await w.subscriber.wait_for(lambda ms: len(ms) == 4)
        assert [m.kind for m in w.subscriber.snapshot()[2:]] == ["DDEATH", "NDEATH"]
        assert not device.born


async def test_replayer_sends_the_buffer_after_a_birth(tmp_path: Path, plc_host: str) -> None:
    async with wired(tmp_path, plc_host) as w:
        device = device_of("m1013", w.catalogue, number=1)
        device.born = True
        buffer = DiskBuffer(tmp_path / "buffer", 1 << 20)
        topic = w.topics.device_topic(MessageType.DDATA, "m1013")
        for stamp_ms in (1000, 2000, 3000):
            payload = make_payload(stamp_ms, None)
            # Buffered when the robot was the settings' third: its place is taken from now.
            add_metric(
                payload,
                alias=3 * ALIAS_STRIDE + 5,
                timestamp_ms=stamp_ms,
                datatype=DataType.BOOLEAN,
                value=True,
            )
            buffer.append(topic, payload.SerializeToString())
        replayer = replayer_of(w, {"m1013": device}, buffer)
        replayer.status.active = False  # not born: nothing goes out, nothing is lost
        replayer.after_birth()
        await eventually(lambda: not replayer.running)
        assert buffer.records_buffered == 3 and replayer.replayed == 0
        replayer.status.active = True
        replayer.after_birth()
        await w.subscriber.wait_for(lambda ms: len(ms) == 3)
        await eventually(lambda: not replayer.running)
        replayed = w.subscriber.snapshot()
        assert [m.metrics[0].timestamp for m in replayed] == [1000, 2000, 3000]
        assert all(m.metrics[0].is_historical for m in replayed)
        assert {(m.metrics[0].alias, m.metrics[0].datatype) for m in replayed} == {
            (ALIAS_STRIDE + 5, None)
        }
        assert replayer.replayed == 3 and buffer.records_buffered == 0
        assert device.messages["DDATA_historical"] == 3
        await replayer.background.cancel()


async def test_reports_birth_data_by_exception_buffer_and_death(
    tmp_path: Path, plc_host: str
) -> None:
    async with wired(tmp_path, plc_host) as w:
        device = device_of("m1013", w.catalogue)
        devices = {"m1013": device}
        buffer = DiskBuffer(tmp_path / "buffer", 1 << 20)
        replayer = replayer_of(w, devices, buffer)
        status = replayer.status
        births = BirthWriter(w.topics, w.catalogue, devices, w.publisher, replayer)
        reports = DeviceReports(
            topics=w.topics,
            catalogue=w.catalogue,
            devices=devices,
            births=births,
            publisher=w.publisher,
            buffer=buffer,
            status=status,
            period_s=0.1,
        )
        reports.tick(device)  # no frame of this connection yet: nothing to say
        frame = standing_frame()
        feed(device, frame)
        reports.tick(device)
        assert device.born
        frame = di_changed(frame)
        feed(device, frame)
        reports.tick(device)
        await w.subscriber.wait_for(lambda ms: len(ms) == 2)
        dbirth, ddata = w.subscriber.snapshot()
        assert (dbirth.kind, ddata.kind) == ("DBIRTH", "DDATA")
        di0 = next(m for m in w.catalogue.metrics if m.field == "controlbox_di" and m.index == 0)
        assert [(m.alias, m.value) for m in ddata.metrics] == [
            (device.alias_base + di0.offset, frame.controlbox_di[0])
        ]
        status.active = False  # the broker away: kept on disk
        feed(device, di_changed(frame))
        reports.tick(device)
        assert buffer.records_buffered == 1 and device.messages["DDATA_buffered"] == 1
        status.active = True
        cast("StandInRobot", device.robot).connection.down_since = time.time()
        reports.tick(device)
        await w.subscriber.wait_for(lambda ms: len(ms) == 3)
        assert w.subscriber.snapshot()[-1].kind == "DDEATH" and not device.born
        assert reports.tick_seconds == 0.0  # counted by its loop, not by a tick called alone


async def test_command_handler_rebirth_and_what_it_refuses(tmp_path: Path, plc_host: str) -> None:
    async with wired(tmp_path, plc_host) as w:
        replayer = replayer_of(w, {}, DiskBuffer(tmp_path / "buffer", 1 << 20))
        status = replayer.status
        handler = CommandHandler(
            topics=w.topics,
            catalogue=w.catalogue,
            devices={},
            births=BirthWriter(w.topics, w.catalogue, {}, w.publisher, replayer),
            status=status,
            background=replayer.background,
            writer=door_writer("parts", "a test"),
            writes_enabled=False,
        )
        rebirth = encode_command([("Node Control/Rebirth", None, BOOLEAN, True)])
        ncmd = w.topics.node_topic(MessageType.NCMD)
        handler.on_command(ncmd, rebirth)
        await w.subscriber.wait_for(lambda ms: [m.kind for m in ms] == ["NBIRTH"])
        handler.on_command(ncmd, b"\xff not a payload")
        handler.on_command(w.topics.device_topic(MessageType.DCMD, "nobody"), rebirth)
        assert handler.bad_commands == 2
        status.stopping = True  # the service stops: no command is read any more
        handler.on_command(ncmd, b"\xff not a payload")
        assert handler.bad_commands == 2 and not handler.commands
        await replayer.background.cancel()


def test_primary_host_state_in_order() -> None:
    host = PrimaryHost("scada")
    assert not host.online
    assert host.read(orjson.dumps({"online": True, "timestamp": 20})) is True
    assert host.read(orjson.dumps({"online": False, "timestamp": 10})) is None  # older
    assert host.online
    assert host.read(b'{"online": "yes", "timestamp": 30}') is None
    assert host.read(b"not json") is None
    assert host.malformed == 2
    assert host.read(orjson.dumps({"online": False, "timestamp": 30})) is False
    assert not host.online and PrimaryHost(None).online


async def test_connection_waits_for_the_primary_host_then_leaves(
    tmp_path: Path, plc_host: str
) -> None:
    async with mosquitto(plc_host, tmp_path) as broker, Subscriber(broker) as subscriber:
        topics, catalogue = Topics(GROUP, NODE), Catalogue({})
        status, background = NodeStatus(), Background()
        publisher = Publisher(NodeSession(tmp_path / "bdseq"))
        replayer = Replayer(
            topics=topics,
            devices={},
            buffer=DiskBuffer(tmp_path / "buffer", 1 << 20),
            publisher=publisher,
            status=status,
            background=background,
        )
        births = BirthWriter(topics, catalogue, {}, publisher, replayer)
        host = PrimaryHost("scada")
        connection = NodeConnection(
            options=ClientOptions(
                BrokerAddress.parse(broker.url), "parts-node", "", "", None, None, None
            ),
            topics=topics,
            host=host,
            devices={},
            publisher=publisher,
            births=births,
            commands=CommandHandler(
                topics=topics,
                catalogue=catalogue,
                devices={},
                births=births,
                status=status,
                background=background,
                writer=door_writer("parts", "a test"),
                writes_enabled=False,
            ),
            status=status,
            background=background,
        )
        connection.start()
        try:
            await eventually(lambda: status.online)
            assert not status.active and connection.connections == 1
            state = {"online": True, "timestamp": int(time.time() * 1000)}
            subscriber.publish(topics.state_topic("scada"), orjson.dumps(state), retain=True)
            await eventually(lambda: status.active)
            await subscriber.wait_for(lambda _: subscriber.of("NBIRTH"))
            assert {m.name: m.value for m in subscriber.of("NBIRTH")[0].metrics}[BD_SEQ] == 0
        finally:
            status.stopping = True
            await background.cancel()
            await connection.stop()
        await subscriber.wait_for(lambda _: subscriber.of("NDEATH"))
        assert len(subscriber.of("NBIRTH")) == 1
        assert not status.online


def test_metrics_view_reads_the_parts(tmp_path: Path) -> None:
    """The families in 58f13a2's order, each read from the part that counts it."""
    topics, catalogue = Topics(GROUP, NODE), Catalogue({})
    status, background = NodeStatus(online=True), Background()
    publisher = Publisher(NodeSession(None))
    device = device_of("m1013", catalogue)
    devices = {"m1013": device}
    buffer = DiskBuffer(tmp_path / "buffer", 1 << 20)
    parts = report_parts(
        topics,
        catalogue,
        devices,
        publisher=publisher,
        buffer=buffer,
        status=status,
        background=background,
    )
    replayer, births, reports = parts.replayer, parts.births, parts.reports
    commands = CommandHandler(
        topics=topics,
        catalogue=catalogue,
        devices=devices,
        births=births,
        status=status,
        background=background,
        writer=door_writer("parts", "a test"),
        writes_enabled=False,
    )
    host = PrimaryHost("scada")
    connection = NodeConnection(
        options=ClientOptions(
            BrokerAddress.parse("mqtt://127.0.0.1"), "x", "", "", None, None, None
        ),
        topics=topics,
        host=host,
        devices=devices,
        publisher=publisher,
        births=births,
        commands=commands,
        status=status,
        background=background,
    )
    publisher.count(None, "NBIRTH", 100)
    publisher.count(device, "DBIRTH", 2000)
    connection.reconnects, replayer.replayed, reports.tick_seconds = 2, 7, 0.5
    buffer.records_set_aside = 3
    commands.commands["done"] += 1
    commands.bad_commands, host.malformed = 1, 2
    view = NodeMetrics(
        status=status,
        connection=connection,
        publisher=publisher,
        devices=devices,
        buffer=buffer,
        replayer=replayer,
        reports=reports,
        commands=commands,
        host=host,
    )
    families = {name: samples for name, _, _, samples in view.metric_families()}
    assert list(families) == [
        "sparkplug_broker_connected",
        "sparkplug_born",
        "sparkplug_reconnects_total",
        "sparkplug_connect_refusals_total",
        "sparkplug_messages_total",
        "sparkplug_published_bytes_total",
        "sparkplug_buffered_messages",
        "sparkplug_buffered_bytes",
        "sparkplug_buffer_dropped_total",
        "sparkplug_buffer_set_aside_total",
        "sparkplug_replayed_total",
        "sparkplug_frames_dropped_total",
        "sparkplug_tick_seconds_total",
        "sparkplug_commands_total",
    ]
    assert families["sparkplug_broker_connected"] == [({}, 1.0)]
    assert families["sparkplug_born"] == [({}, 0.0)]
    assert families["sparkplug_reconnects_total"] == [({}, 2.0)]
    assert families["sparkplug_messages_total"] == [
        ({"type": "NBIRTH"}, 1.0),
        ({"robot": "m1013", "type": "DBIRTH"}, 1.0),
    ]
    assert families["sparkplug_published_bytes_total"][1] == (
        {"robot": "m1013", "type": "DBIRTH"},
        2000.0,
    )
    assert families["sparkplug_replayed_total"] == [({}, 7.0)]
    assert families["sparkplug_buffer_set_aside_total"] == [({}, 3.0)]
    assert families["sparkplug_tick_seconds_total"] == [({}, 0.5)]
    assert families["sparkplug_commands_total"] == [
        ({"outcome": "done"}, 1.0),
        ({"outcome": "malformed"}, 3.0),
    ]
