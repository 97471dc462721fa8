"""The edge node's parts built alone, without a service, for the tests of those parts and
``bench/sparkplug_tick``: a robot as they read it (its name and frames, whether its connection
is up and which one, its command image and control holder), and the reports wired to their
replay and births as ``EdgeNode`` wires them."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import SimpleNamespace
from typing import TYPE_CHECKING, cast

from cobot_hmi.service.robots.frame_notifier import FrameNotifier
from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.catalogue import Catalogue
from cobot_hmi.sparkplug.event_metrics import AlarmDeclaration
from cobot_hmi.sparkplug.node.births import BirthWriter
from cobot_hmi.sparkplug.node.core import Background, NodeStatus, Publisher
from cobot_hmi.sparkplug.node.device import Device
from cobot_hmi.sparkplug.node.replay import Replayer
from cobot_hmi.sparkplug.node.reports import DeviceReports
from cobot_hmi.sparkplug.topics import Topics

if TYPE_CHECKING:
    from cobot_hmi.service.robots.robot import RobotRuntime


class StandInRobot:
    """What a ``Device`` and the reports read of a robot (module docstring)."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.frames = FrameNotifier(name)
        self.connection = SimpleNamespace(down_since=None, connects=1)
        self.link = SimpleNamespace(command=None)
        self.control = SimpleNamespace(holder=None)


def device_of(
    name: str,
    catalogue: Catalogue,
    number: int = 1,
    alarms: Sequence[AlarmDeclaration] = (),
) -> Device:
    """The edge node's device of a stand-in robot called ``name``."""
    return Device(cast("RobotRuntime", StandInRobot(name)), number, catalogue, alarms)


@dataclass(frozen=True)
class ReportParts:
    replayer: Replayer
    births: BirthWriter
    reports: DeviceReports


def report_parts(
    topics: Topics,
    catalogue: Catalogue,
    devices: Mapping[str, Device],
    *,
    publisher: Publisher,
    buffer: DiskBuffer,
    status: NodeStatus,
    background: Background | None = None,
    period_s: float = 0.1,
) -> ReportParts:
    """The replay, births and reports of ``devices``, wired to each other."""
    replayer = Replayer(
        topics=topics,
        devices=devices,
        buffer=buffer,
        publisher=publisher,
        status=status,
        background=background or Background(),
    )
    births = BirthWriter(topics, catalogue, devices, publisher, replayer)
    reports = DeviceReports(
        topics=topics,
        catalogue=catalogue,
        devices=devices,
        births=births,
        publisher=publisher,
        buffer=buffer,
        status=status,
        period_s=period_s,
    )
    return ReportParts(replayer, births, reports)
