"""The DDATA the edge node builds, byte for byte against a reference written the plain way
(issue 40 made the reports' path cheaper: one comparison per analog value in a comprehension, one
protobuf call per metric): every metric compared one by one with ``rbe.moved`` and appended with
``payload.add_metric``, as the node did before. Frames of the emulated robot running its demo
program, with NaN, infinities, coded values and deadbands of 0, less than 0 and NaN among them;
the node's DDATA read back from its disk buffer (the broker away: the payload as built, without
``seq``, which the publisher alone adds).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, cast

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cobot_hmi.codec import Frame
from cobot_hmi.emulator.robot.simulated import RobotSettings, SimulatedRobot
from cobot_hmi.service.robots.frame_notifier import FrameRecord
from cobot_hmi.service.service_settings import DEFAULT_DEADBANDS
from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.catalogue import Catalogue, MetricDef, Role, state_name
from cobot_hmi.sparkplug.node.core import NodeStatus, Publisher
from cobot_hmi.sparkplug.node.device import Device
from cobot_hmi.sparkplug.node.reports import DeviceReports
from cobot_hmi.sparkplug.payload import (
    DataType,
    MetricValue,
    Payload,
    Property,
    add_metric,
    data_metric_writer,
    make_payload,
    parse_payload,
)
from cobot_hmi.sparkplug.rbe import moved, threshold
from cobot_hmi.sparkplug.session import NodeSession
from cobot_hmi.sparkplug.topics import Topics
from sparkplug_parts_support import device_of, report_parts

if TYPE_CHECKING:
    pass

FRAMES_PER_TICK = 10


def demo_frames(count: int) -> list[Frame]:
    """The demo program's frames at RPI 10 ms, with what the reports must also get right."""
    robot = SimulatedRobot(RobotSettings(), start_s=0.0)
    frames = []
    for i in range(count):
        frame = robot.produce_frame(i * 0.01)
        joints = list(frame.joint_position)
        if 300 <= i < 340:
            joints[0] = math.nan  # into NaN and out of it
        if 500 <= i < 520:
            joints[1] = math.inf
            joints[2] = -math.inf
        if 700 <= i < 720:
            joints[3] = -0.0
        types = list(frame.analog_input_type)
        types[0] = (i // 130) % 3  # coded: a name property (2 is past the names: none)
        frame = frame._replace(
            joint_position=tuple(joints),
            analog_input_type=tuple(types),
            robot_state=(frame.robot_state + i // 250) % 20,
        )
        frames.append(frame)
    return frames


def value_of(frame: Frame, metric: MetricDef) -> MetricValue:
    assert metric.field is not None
    value = getattr(frame, metric.field)
    return cast("MetricValue", value if metric.index is None else value[metric.index])


class Reference:
    """One robot's DDATA the plain way: each metric on its own."""

    def __init__(self, catalogue: Catalogue, alias_base: int, first: Frame) -> None:
        self.catalogue = catalogue
        self.alias_base = alias_base
        self.discrete = [m for m in catalogue.metrics if m.role is Role.DISCRETE]
        self.analog = [m for m in catalogue.metrics if m.role is Role.ANALOG]
        self.last = {m.offset: value_of(first, m) for m in self.discrete}
        self.reported = {m.offset: value_of(first, m) for m in self.analog}

    def ddata(self, records: list[FrameRecord]) -> Payload | None:
        changes: list[tuple[MetricDef, MetricValue, int]] = []
        for record in records:
            for m in self.discrete:
                value = value_of(record.frame, m)
                if value != self.last[m.offset]:
                    changes.append((m, value, int(record.received_at_s * 1000)))
                    self.last[m.offset] = value
        if records:
            newest = records[-1]
            for m in self.analog:
                value = value_of(newest.frame, m)
                old = self.reported[m.offset]
                assert isinstance(value, float) and isinstance(old, float)
                if moved(value, old, m.deadband):
                    changes.append((m, value, int(newest.received_at_s * 1000)))
                    self.reported[m.offset] = value
        if not changes:
            return None
        payload = make_payload(0, None)
        for m, value, stamp in changes:
            name = state_name(m, value)
            add_metric(
                payload,
                alias=self.alias_base + m.offset,
                timestamp_ms=stamp,
                datatype=m.datatype,
                value=value,
                properties=(Property("name", DataType.STRING, name),) if name else (),
                with_datatype=False,
            )
        return payload


def reports_of(
    catalogue: Catalogue, device: Device, buffer: DiskBuffer, tmp: Path
) -> DeviceReports:
    parts = report_parts(
        Topics("plant", "golden"),
        catalogue,
        {device.device_name: device},
        publisher=Publisher(NodeSession(tmp / "bdseq")),
        buffer=buffer,
        status=NodeStatus(),  # not born: every DDATA goes to the buffer as built
    )
    return parts.reports


DEADBANDS = [
    DEFAULT_DEADBANDS,
    {},  # every change
    {"joint_position": -1.0, "degree/s": 0.1, "A": math.nan, "tcp_position": 0.0},
]


@pytest.mark.parametrize("deadbands", DEADBANDS, ids=["default", "zero", "odd"])
async def test_ddata_bytes_as_the_plain_way_builds_them(
    tmp_path: Path, deadbands: dict[str, float]
) -> None:
    catalogue = Catalogue(deadbands)
    device = device_of("m1013", catalogue, number=2)
    buffer = DiskBuffer(tmp_path / "buffer", 64 << 20)
    reports = reports_of(catalogue, device, buffer, tmp_path)
    frames = demo_frames(2400)
    records = [FrameRecord(i, 1.7e9 + i * 0.01, f, i, b"") for i, f in enumerate(frames)]
    reference = Reference(catalogue, device.alias_base, frames[0])
    device.on_frames("m1013", records[:1])
    reports.tick(device)  # alive: the first frame is the baseline
    expected: list[Payload] = []
    at = 1
    for size in [FRAMES_PER_TICK] * 200 + [1, 0, 3, 0] * 20:
        batch = records[at : at + size]
        at += size
        device.on_frames("m1013", batch)
        reports.tick(device)
        payload = reference.ddata(batch)
        if payload is not None:
            expected.append(payload)
    got = [data for path in buffer.sealed() for _, data in buffer.read(path)]
    assert len(got) == len(expected) > 200
    for data, payload in zip(got, expected, strict=True):
        payload.timestamp = parse_payload(data).timestamp  # the node's clock when it built it
        assert data == payload.SerializeToString()
    named = sum(1 for p in expected for m in p.metrics if m.properties.keys)
    assert named > 10  # the coded values' names were in the comparison


@given(
    new=st.floats(),
    old=st.floats(),
    deadband=st.one_of(st.floats(), st.sampled_from([0.0, -0.0, -1.0, 0.01, math.nan])),
)
def test_one_comparison_is_moved_without_nan(new: float, old: float, deadband: float) -> None:
    if not (math.isnan(new) or math.isnan(old)):
        assert moved(new, old, deadband) == (abs(new - old) >= threshold(deadband))


@given(
    value=st.one_of(
        st.booleans(),
        st.integers(-(2**63), 2**64 - 1),
        st.floats(allow_nan=False),
        st.text(max_size=20),
    ),
    datatype=st.sampled_from(list(DataType)),
    alias=st.integers(0, 2**64 - 1),
    stamp=st.integers(0, 2**64 - 1),
)
def test_a_data_metric_in_one_call_is_add_metric_s(
    value: MetricValue, datatype: DataType, alias: int, stamp: int
) -> None:
    plain, quick = make_payload(5, None), make_payload(5, None)
    try:
        add_metric(
            plain,
            alias=alias,
            timestamp_ms=stamp,
            datatype=datatype,
            value=value,
            with_datatype=False,
        )
    except (TypeError, ValueError, OverflowError) as error:  # not a value of that type
        with pytest.raises(type(error)):
            data_metric_writer(datatype)(quick.metrics, alias, stamp, value)
        return
    data_metric_writer(datatype)(quick.metrics, alias, stamp, value)
    assert quick.SerializeToString() == plain.SerializeToString()
