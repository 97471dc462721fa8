"""The Sparkplug parts on their own: the disk buffer's bound and replay, the settings' deadbands
and broker URL, the catalogue against the layout, payloads read back by the tests' own
wire-format reader, and report by exception (every bit transition, deadbands, NaN)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cobot_hmi.codec import zero_frame
from cobot_hmi.layout import T2O_FIELDS
from cobot_hmi.service.config.loading import load_settings
from cobot_hmi.service.robots.frame_notifier import FrameNotifier, FrameRecord
from cobot_hmi.service.service_settings import DEFAULT_DEADBANDS, SettingsError
from cobot_hmi.settings import HmiSettings
from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.catalogue import ALIAS_STRIDE, Catalogue
from cobot_hmi.sparkplug.mqtt_client import BrokerAddress
from cobot_hmi.sparkplug.payload import (
    DataType,
    Property,
    add_metric,
    make_payload,
    metric_value,
    parse_payload,
)
from cobot_hmi.sparkplug.rbe import Reporter, moved
from cobot_hmi.sparkplug.session import NodeSession
from cobot_hmi.sparkplug.topics import MessageType, Topics
from frame_support import CollectedFrames
from mosquitto_support import decode_payload, encode_command

# --------------------------------------------------------------------------- the buffer


def test_buffer_keeps_its_bound_and_counts_what_it_drops(tmp_path: Path) -> None:
    buffer = DiskBuffer(tmp_path / "buffer", max_bytes=256 * 1024)
    record = b"x" * 1000
    for i in range(600):
        assert buffer.append(f"spBv1.0/g/DDATA/n/r{i % 3}", record)
    on_disk = sum(p.stat().st_size for p in (tmp_path / "buffer").glob("*.seg"))
    assert on_disk == buffer.bytes_buffered <= 256 * 1024
    assert buffer.records_dropped > 0
    assert buffer.records_buffered + buffer.records_dropped == 600
    # What is left is the newest, in order, and survives a restart of the service.
    again = DiskBuffer(tmp_path / "buffer", max_bytes=256 * 1024)
    assert again.records_buffered == buffer.records_buffered
    seen = []
    for path in again.sealed():
        seen += again.read(path)
        again.finish(path)
    assert again.sealed() == []  # the fresh segment for new records is empty
    assert len(seen) == buffer.records_buffered
    assert seen[-1] == ("spBv1.0/g/DDATA/n/r2", record)  # record 599
    assert again.records_buffered == 0
    assert not list((tmp_path / "buffer").glob("*.seg"))


def test_buffer_put_back_and_a_torn_record(tmp_path: Path) -> None:
    buffer = DiskBuffer(tmp_path, max_bytes=1024 * 1024)
    for i in range(5):
        buffer.append("t", bytes([i]))
    [path] = buffer.sealed()
    buffer.append("t", b"new")  # while the replay runs: into a fresh segment
    records = buffer.read(path)
    buffer.put_back(path, records[2:])  # two went out before the broker left again
    assert buffer.records_buffered == 4
    with path.open("ab") as file:
        file.write(b"\x01\x00\x10\x00\x00\x00t\x00")  # a record cut short by a crash
    restarted = DiskBuffer(tmp_path, max_bytes=1024 * 1024)
    first, second = restarted.sealed()
    assert restarted.read(first) == [("t", b"\x02"), ("t", b"\x03"), ("t", b"\x04")]
    assert restarted.read(second) == [("t", b"new")]


def test_buffer_off_drops_and_counts(tmp_path: Path) -> None:
    buffer = DiskBuffer(tmp_path, max_bytes=0)
    assert not buffer.append("t", b"x")
    assert buffer.records_dropped == 1
    assert buffer.sealed() == []


# --------------------------------------------------------------------------- settings


def test_deadbands_from_a_flag_and_the_defaults() -> None:
    settings = load_settings(
        {"sparkplug_deadbands": "degree=0.5, joint_torque=2"}, None, None, HmiSettings
    )
    assert settings.sparkplug.sparkplug_deadbands["degree"] == 0.5
    assert settings.sparkplug.sparkplug_deadbands["joint_torque"] == 2.0
    assert settings.sparkplug.sparkplug_deadbands["mm"] == DEFAULT_DEADBANDS["mm"]
    units = {f.unit for f in T2O_FIELDS if f.unit}
    assert units == set(DEFAULT_DEADBANDS)  # every unit of the layout has a default


@pytest.mark.parametrize(
    ("flags", "named"),
    [
        ({"sparkplug_deadbands": "furlong=1"}, "furlong"),
        ({"sparkplug_deadbands": "degree"}, "UNIT=VALUE"),
        ({"sparkplug_deadbands": "degree=-1"}, "not negative"),
        ({"sparkplug_deadbands": "degree=lots"}, "sparkplug_deadbands"),
        ({"mqtt_url": "http://broker:1883"}, "mqtt_url"),
        ({"sparkplug_group": "a/b"}, "sparkplug_group"),
        ({"sparkplug_node": "cell#1"}, "sparkplug_node"),
        ({"sparkplug_max_rate_hz": 0}, "sparkplug_max_rate_hz"),
        ({"mqtt_ca_file": "/nonexistent/ca.pem"}, "mqtt_ca_file.*not a readable file"),
        ({"mqtt_client_key": "/nonexistent/key.pem"}, "mqtt_client_key"),
    ],
)
def test_bad_sparkplug_settings_are_named(flags: dict[str, object], named: str) -> None:
    with pytest.raises(SettingsError, match=named):
        load_settings(flags, None, None, HmiSettings)


def test_deadbands_from_a_toml_table(tmp_path: Path) -> None:
    config = tmp_path / "cell.toml"
    config.write_text('[sparkplug_deadbands]\n"N·m" = 0.2\njoint_position = 0.05\n')
    settings = load_settings({}, {}, config, HmiSettings)
    assert settings.sparkplug.sparkplug_deadbands["N·m"] == 0.2
    assert settings.sparkplug.sparkplug_deadbands["joint_position"] == 0.05


def test_broker_urls() -> None:
    assert BrokerAddress.parse("mqtt://broker") == BrokerAddress("broker", 1883, False)
    assert BrokerAddress.parse("mqtts://10.0.0.5") == BrokerAddress("10.0.0.5", 8883, True)
    assert str(BrokerAddress.parse("mqtt://b:1999/")) == "mqtt://b:1999"
    with pytest.raises(ValueError, match="mqtt://"):
        BrokerAddress.parse("tcp://b:1883")


# --------------------------------------------------------------------------- catalogue, topics


def test_the_catalogue_is_the_layout() -> None:
    catalogue = Catalogue(DEFAULT_DEADBANDS)
    names = [m.name for m in catalogue.metrics]
    assert len(names) == len(set(names)) < ALIAS_STRIDE
    count = sum(1 if f.scalar else f.count for f in T2O_FIELDS)
    t2o = catalogue.metrics[:count]
    assert [m.field for m in t2o] == [
        f.name for f in T2O_FIELDS for _ in range(1 if f.scalar else f.count)
    ]
    by_name = catalogue.by_name
    assert by_name["joint_motor_current/J 6"].unit == "A"
    assert by_name["joint_motor_current/J 6"].deadband == DEFAULT_DEADBANDS["A"]
    assert by_name["analog_input_type/AI 1"].datatype is DataType.UINT8
    assert by_name["bit_output_registers/Register 63"].datatype is DataType.BOOLEAN
    assert by_name["command/bit_input_registers/Register 0"].writable
    assert not by_name["controlbox_do/DO 1"].writable
    custom = Catalogue({**DEFAULT_DEADBANDS, "joint_torque": 3.0})
    assert custom.by_name["joint_torque/J 2"].deadband == 3.0
    assert custom.by_name["joint_external_torque/J 2"].deadband == DEFAULT_DEADBANDS["N·m"]


def test_topics() -> None:
    topics = Topics("plant", "cell-7")
    assert topics.device_topic(MessageType.DDATA, "m1013") == "spBv1.0/plant/DDATA/cell-7/m1013"
    parsed = topics.parse("spBv1.0/plant/DCMD/cell-7/m1013")
    assert parsed is not None and parsed.device == "m1013"
    assert parsed.message_type is MessageType.DCMD
    for foreign in (
        "spBv1.0/other/DCMD/cell-7/m1013",
        "spBv1.0/plant/DCMD/cell-8/m1013",
        "spBv1.0/plant/XCMD/cell-7",
        "spAv1.0/plant/NCMD/cell-7",
        "spBv1.0/plant/DCMD/cell-7/m1013/extra",
    ):
        assert topics.parse(foreign) is None


def test_bd_seq_is_kept_and_wraps(tmp_path: Path) -> None:
    state = tmp_path / "bdseq"
    session = NodeSession(state)
    assert session.next_connection(advance=False) == 0
    assert session.next_connection(advance=False) == 0  # the attempt never sent CONNECT
    assert session.next_connection(advance=True) == 1
    assert NodeSession(state).next_connection(advance=False) == 2
    state.write_text("255\n")
    assert NodeSession(state).bd_seq == 0
    state.write_text("garbage")
    assert NodeSession(state).bd_seq == 0
    assert session.birth_seq() == 0
    assert [session.next_seq() for _ in range(256)][-2:] == [255, 0]


# --------------------------------------------------------------------------- payloads


@given(
    value=st.floats(width=32, allow_nan=False),
    flag=st.booleans(),
    small=st.integers(0, 255),
    text=st.text(max_size=40),
    stamp=st.integers(0, 2**63 - 1),
)
def test_payloads_read_back_by_an_independent_reader(
    value: float, flag: bool, small: int, text: str, stamp: int
) -> None:
    payload = make_payload(stamp, 7)
    add_metric(payload, alias=1001, timestamp_ms=stamp, datatype=DataType.FLOAT, value=value)
    add_metric(payload, alias=1002, timestamp_ms=stamp, datatype=DataType.BOOLEAN, value=flag)
    add_metric(
        payload,
        alias=None,
        name="robot_state",
        timestamp_ms=stamp,
        datatype=DataType.UINT8,
        value=small,
        properties=[Property("name", DataType.STRING, text)],
    )
    add_metric(payload, alias=5, timestamp_ms=stamp, datatype=DataType.UINT64, value=2**40)
    data = payload.SerializeToString()
    message = decode_payload("spBv1.0/g/DDATA/n/r", data, 0.0)
    assert (message.timestamp, message.seq) == (stamp, 7)
    got = [(m.alias, m.name, m.datatype, m.value, m.timestamp) for m in message.metrics]
    assert got == [
        (1001, None, 9, value, stamp),
        (1002, None, 11, flag, stamp),
        (None, "robot_state", 5, small, stamp),
        (5, None, 8, 2**40, stamp),
    ]
    assert message.metrics[2].properties == {"name": text}
    assert [metric_value(m) for m in parse_payload(data).metrics] == [value, flag, small, 2**40]


def test_commands_written_by_the_test_encoder_parse() -> None:
    data = encode_command([("Node Control/Rebirth", None, 11, True), (None, 1042, 9, 4.5)])
    metrics = parse_payload(data).metrics
    assert metrics[0].name == "Node Control/Rebirth"
    assert metric_value(metrics[0]) is True
    assert (metrics[1].alias, metric_value(metrics[1])) == (1042, 4.5)


def test_garbage_is_a_payload_error() -> None:
    from cobot_hmi.sparkplug.payload import PayloadError

    with pytest.raises(PayloadError):
        parse_payload(b"\x12\xff\xff\xff\xff\x0f")


# --------------------------------------------------------------------------- report by exception


def test_every_transition_between_two_reports() -> None:
    catalogue = Catalogue(DEFAULT_DEADBANDS)
    reporter = Reporter(catalogue)
    base = zero_frame()
    reporter.baseline(base)
    di = list(base.controlbox_di)
    items = []
    for i in range(6):
        di[2] = i % 2 == 0
        frame = base._replace(controlbox_di=tuple(di), robot_state=i)
        items.append(FrameRecord(i, 1000.0 + i / 100, frame, i, b""))
    changes = reporter.discrete_changes(items)
    offset = catalogue.by_name["controlbox_di/DI 3"].offset
    state = catalogue.by_name["robot_state"].offset
    assert [(v, t) for o, v, t in changes if o == offset] == [
        (i % 2 == 0, 1000000 + i * 10) for i in range(6)
    ]
    assert [v for o, v, _ in changes if o == state] == [1, 2, 3, 4, 5]
    assert reporter.discrete_changes([FrameRecord(7, 1001.0, items[-1][2], 7, b"")]) == []


def test_analog_deadband_is_against_the_last_reported_value() -> None:
    catalogue = Catalogue({**DEFAULT_DEADBANDS, "joint_position": 1.0})
    reporter = Reporter(catalogue)
    frame = zero_frame()
    reporter.baseline(frame)
    j1 = catalogue.by_name["joint_position/J 1"].offset
    reported = []
    for step in range(1, 30):  # creeping 0.3° at a time: reported every 4th step
        moved_frame = frame._replace(joint_position=(0.3 * step, 0, 0, 0, 0, 0))
        values, moved_at = reporter.analog_moved(moved_frame)
        reported += [values[i] for i in moved_at if reporter.analog_offsets[i] == j1]
    assert reported == pytest.approx([1.2, 2.4, 3.6, 4.8, 6.0, 7.2, 8.4])


def test_moved() -> None:
    assert moved(1.0, 0.0, 1.0)
    assert not moved(0.99, 0.0, 1.0)
    assert moved(0.001, 0.0, 0.0)
    assert not moved(0.0, 0.0, 0.0)
    assert moved(math.nan, 0.0, 1.0)
    assert moved(0.0, math.nan, 1.0)
    assert not moved(math.nan, math.nan, 0.0)


# --------------------------------------------------------------------------- frame consumers


def test_a_consumer_s_queue_is_bounded_and_counts_its_drops() -> None:
    notifier = FrameNotifier("r")
    consumer = CollectedFrames(notifier, 3)
    frames = [zero_frame()._replace(robot_state=i) for i in range(5)]
    for i, frame in enumerate(frames):
        notifier.publish(frame, b"", 1000.0 + i, i)
    assert consumer.dropped == 2
    taken = consumer.take()
    assert [record.frame.robot_state for record in taken] == [2, 3, 4]
    assert [record.seq for record in taken] == [3, 4, 5]  # the notifier's own sequence
    assert consumer.take() == []
    consumer.close()
    notifier.publish(frames[0], b"", 2000.0, 6)
    assert consumer.take() == []
