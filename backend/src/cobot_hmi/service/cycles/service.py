"""Layer: service. Every robot's cycle meter on its frames, and the measured cycles to the store.

Each robot with a ``cycle_trigger`` gets a ``CycleMeter``, registered with the robot's frame
notifier as a consumer on the web loop (``robots.frame_notifier``: every frame, O(1) on the cyclic
thread, drops counted). The meter reads each frame's own receive time, so when the loop runs it
changes when a cycle is written, never what it measures.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Final

from cobot_hmi.service.cycles.meter import Cycle, CycleMeter
from cobot_hmi.service.cycles.store import CycleStore
from cobot_hmi.service.events.text import Event
from cobot_hmi.service.robots.frame_notifier import FrameRecord, Runs
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.storage.store import Store

QUEUE_FRAMES: Final = 8192
"""Frames a meter may fall behind by (~80 s at 10 ms) before the oldest are dropped."""


class CycleConsumer:
    """One robot's meter as a frame consumer (``robots.frame_notifier.FrameConsumer``); each
    measured cycle is stored and announced on the event bus (a ``cycle`` event: the plots'
    markers)."""

    name = "cycles"
    runs = Runs.LOOP
    queue_frames = QUEUE_FRAMES

    def __init__(
        self,
        meter: CycleMeter,
        store: CycleStore,
        last: dict[str, Cycle],
        publish: Callable[[Event], None],
    ) -> None:
        self.meter = meter
        self._store = store
        self._last = last
        self._publish = publish

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        observe = self.meter.observe
        for record in records:
            cycle = observe(record.frame, record.received_at_s)
            if cycle is not None:
                self._last[cycle.robot] = cycle
                self._store.submit(cycle)
                event: Event = {
                    "kind": "cycle",
                    "time": cycle.start,
                    "end": cycle.end,
                    "duration_s": round(cycle.duration_s, 6),
                }
                if cycle.interruption is not None:
                    event["interruption"] = cycle.interruption
                self._publish(event)


class Cycles:
    """The cell's cycle timing: one meter per robot that has a trigger."""

    def __init__(self, robots: Mapping[str, RobotRuntime], store: Store) -> None:
        self.store = CycleStore(store)
        self.meters: dict[str, CycleMeter] = {}
        self.last: dict[str, Cycle] = {}
        """Each robot's newest measured cycle (also before it is written)."""
        for name, robot in robots.items():
            trigger = robot.settings.cycle_trigger_parsed
            if trigger is not None:
                meter = self.meters[name] = CycleMeter(name, trigger)
                robot.frames.add(CycleConsumer(meter, self.store, self.last, robot.publish_event))

    def start(self) -> None:
        """On the web loop, before the first frame can come."""
        self.store.open()

    async def stop(self) -> None:
        """After the frames stopped: every measured cycle written."""
        await self.store.close()
