"""A robot as the edge node's parts read it, for tests that build those parts alone (a
``Device``, the reports, the replay) without a service: its name and frames, whether its
connection is up (and which one), its command image and control holder."""

from __future__ import annotations

from collections.abc import Sequence
from types import SimpleNamespace
from typing import TYPE_CHECKING, cast

from cobot_hmi.service.robots.frame_notifier import FrameNotifier
from cobot_hmi.sparkplug.catalogue import Catalogue
from cobot_hmi.sparkplug.event_metrics import AlarmDeclaration
from cobot_hmi.sparkplug.node.device import Device

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
