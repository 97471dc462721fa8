"""Layer: service (Sparkplug). The edge node as a consumer of the service's events
(``service.events.bus``): each robot's alarm, cycle and health events become its event metrics'
changes (``event_metrics``), reported with its next tick.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Final

from cobot_hmi.service.events.text import Event
from cobot_hmi.sparkplug.event_metrics import alarm_declarations
from cobot_hmi.sparkplug.node.device import Device

KINDS: Final = frozenset({"alarm", "cycle", "health"})


class EventFeed:
    """An ``EventConsumer`` of the bus: on the web loop, quick (the changes are queued on the
    robot's device, published by its loop)."""

    name: Final = "sparkplug"

    def __init__(self, devices: Mapping[str, Device]) -> None:
        self.devices = devices

    def restored(self) -> None:
        """Each robot's alarms as its engine has them once the service restored them (before
        the first birth, which carries them)."""
        for device in self.devices.values():
            device.events.restore(alarm_declarations(device.robot.alarms.all()))

    def on_events(self, events: Sequence[Event]) -> None:
        for event in events:
            if event.get("kind") not in KINDS:
                continue
            device = self.devices.get(str(event.get("robot")))
            if device is not None:
                device.on_event(event)
