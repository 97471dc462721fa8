"""Layer: service. Every robot's cycle meter on its frames, and the measured cycles to the store.

Each robot with a ``cycle_trigger`` gets a ``CycleMeter`` fed by a subscription to its hub
(``Hub.subscribe``: every frame, O(1) on the cyclic thread, drops counted), drained on the web
loop every ``DRAIN_S``. The meter reads each frame's own receive time, so the drain period
changes when a cycle is written, never what it measures. (The robot's frame consumer interface,
``robots.frames``, takes this subscription's place once it is in.)
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Mapping
from typing import Final

from cobot_hmi.service.cycles.meter import Cycle, CycleMeter
from cobot_hmi.service.cycles.store import CycleStore
from cobot_hmi.service.robots.hub import FrameSubscription
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.storage.store import Store

log = logging.getLogger(__name__)

DRAIN_S: Final = 0.1
"""How often the meters read the frames queued for them (not what they measure: each frame
carries its receive time)."""
QUEUE_FRAMES: Final = 8192
"""Frames a meter may fall behind by (~80 s at 10 ms) before the oldest are dropped."""


class Cycles:
    """The cell's cycle timing: one meter per robot that has a trigger."""

    def __init__(self, robots: Mapping[str, RobotRuntime], store: Store) -> None:
        self.robots = robots
        self.store = CycleStore(store)
        self.meters: dict[str, CycleMeter] = {}
        for name, robot in robots.items():
            trigger = robot.settings.cycle_trigger_parsed
            if trigger is not None:
                self.meters[name] = CycleMeter(name, trigger)
        self.last: dict[str, Cycle] = {}
        """Each robot's newest measured cycle (also before it is written)."""
        self._subscriptions: dict[str, FrameSubscription] = {}
        self._task: asyncio.Task[None] | None = None

    def start(self) -> None:
        """On the web loop, before the first frame can come."""
        self.store.open()
        for name in self.meters:
            self._subscriptions[name] = self.robots[name].hub.subscribe("cycles", QUEUE_FRAMES)
        if self.meters:
            self._task = asyncio.create_task(self._run(), name="cycles")

    async def stop(self) -> None:
        """After the frames stopped: the last ones measured, every cycle written."""
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
        self.drain()
        for name, subscription in self._subscriptions.items():
            self.robots[name].hub.unsubscribe(subscription)
        self._subscriptions.clear()
        await self.store.close()

    def drain(self) -> None:
        """Every queued frame through its robot's meter; each cycle measured to the store."""
        for name, subscription in self._subscriptions.items():
            meter = self.meters[name]
            for _, time_s, frame, _ in subscription.drain():
                cycle = meter.observe(frame, time_s)
                if cycle is not None:
                    self.last[name] = cycle
                    self.store.submit(cycle)

    async def _run(self) -> None:
        while True:
            await asyncio.sleep(DRAIN_S)
            try:
                self.drain()
            except Exception:  # a bug here must not end the measuring of every robot
                log.exception("cycle timing: drain failed")
