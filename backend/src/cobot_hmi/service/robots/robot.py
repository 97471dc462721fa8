"""Layer: service. One robot of the cell, everything the service keeps for it.

A ``RobotRuntime`` composes one robot's parts, each an object with one job that a test can build
alone: its connection handle (``link``: its originator on the shared cyclic thread), its frames
and their consumers (the WebSocket fan-out, receive intervals, write confirmation, the frame
event watch), its control holder, its write counters (write confirmation and outcome
counters), its alarms, its connection as watched (``connection``: events, counters, connection
alarms, ``robots.connection_watch``) and its identity once read (``robots.identity``). Robots
share only the store, the sessions and the cyclic thread; a robot lost or refused changes
nothing of another.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import Counter
from collections.abc import Callable, Coroutine, Mapping
from dataclasses import dataclass, field
from typing import Any

from cobot_hmi.layout import LAYOUT_VERSION
from cobot_hmi.scanner.originator import ConnectionState, ConnectionStats, OriginatorSettings
from cobot_hmi.service.alarms.alarm_settings import AlarmLimitSettings
from cobot_hmi.service.alarms.engine import AlarmEngine, UserAlarm
from cobot_hmi.service.alarms.persistence import AlarmChange, AlarmStore
from cobot_hmi.service.events.bus import EventBus
from cobot_hmi.service.events.text import Event
from cobot_hmi.service.plant_time import PLANT_ZONE
from cobot_hmi.service.robots.confirmation import FrameWaiters
from cobot_hmi.service.robots.connection_watch import ConnectionWatch
from cobot_hmi.service.robots.control import Control
from cobot_hmi.service.robots.frame_notifier import FrameNotifier
from cobot_hmi.service.robots.identity import IdentityReader, RobotIdentity
from cobot_hmi.service.robots.intervals import ReceiveIntervals
from cobot_hmi.service.robots.link import CyclicLoop, RobotLink
from cobot_hmi.service.robots.robot_settings import RobotSettings
from cobot_hmi.service.robots.watch import FrameEventWatch
from cobot_hmi.service.robots.websocket_fanout import WebSocketFanOut
from cobot_hmi.service.storage.store import Store
from cobot_hmi.service.storage.tags import TagBook
from cobot_hmi.service.web.stream_settings import StreamSettings

log = logging.getLogger(__name__)


@dataclass
class WriteCounters:
    """A robot's writes: how long a write waits for the robot's confirmation, and how many
    ended in each outcome (``confirmed``, ``refused``, ``timeout``, …) for /metrics; the write
    pipeline (``service.writes.pipeline``) counts into them."""

    timeout_s: float
    outcomes: Counter[str] = field(default_factory=Counter)


def _alarm_engine(
    robot: str,
    settings: AlarmLimitSettings,
    *,
    publish: Callable[[Event], None],
    persist: Callable[[AlarmChange], None],
    tags: Callable[[], Mapping[str, str]],
) -> AlarmEngine:
    """The robot's alarm engine with the alarm settings and the user alarms of this robot (or of
    every robot)."""
    return AlarmEngine(
        robot,
        motor_temperature_c=settings.alarm_motor_temperature_c,
        motor_temperature_deadband_c=settings.alarm_motor_temperature_deadband_c,
        gap_rate_per_min=settings.alarm_gap_rate_per_min,
        connection_delay_s=settings.alarm_connection_delay_s,
        shelve_max_s=settings.alarm_shelve_max_s,
        shelve_max_by_priority_s={
            "high": settings.alarm_shelve_max_high_s,
            "medium": settings.alarm_shelve_max_medium_s,
            "low": settings.alarm_shelve_max_low_s,
        },
        consequence_window_s=settings.alarm_consequence_window_s,
        user_alarms=tuple(
            UserAlarm(**alarm.model_dump(exclude={"robot"}))
            for alarm in settings.alarms
            if alarm.robot in (None, robot)
        ),
        publish=publish,
        persist=persist,
        tags=tags,
    )


class RobotRuntime:
    """One robot: connection handle, hub, control, write counters, alarms, connection watch,
    identity.

    Given what it uses and no more: its own settings, its connection's (``originator``), the
    streams' and writes' (``stream``) and the alarm settings (``alarms``)."""

    def __init__(
        self,
        settings: RobotSettings,
        cyclic: CyclicLoop,
        store: Store,
        events: EventBus,
        *,
        originator: OriginatorSettings,
        stream: StreamSettings,
        alarms: AlarmLimitSettings,
    ) -> None:
        self.name = settings.name
        self.settings = settings
        self.store = store
        self._stale_after_s = stream.stale_after_ms / 1000
        self._events = events
        self.frames = FrameNotifier(
            self.name,
            frames_per_wake=max(1, round(stream.ws_batch_ms / settings.rpi_ms)),
            turn_period_s=stream.ws_batch_ms / 1000,
        )
        """Every frame of the robot, published once, to every consumer
        (``robots.frame_notifier``)."""
        self.hub = WebSocketFanOut(
            robot=self.name,
            batch_s=stream.ws_batch_ms / 1000,
            client_queue_frames=stream.ws_queue_frames,
            stall_timeout_s=stream.ws_stall_timeout_s,
        )
        """The WebSocket fan-out: the first consumer, so clients get frames before events."""
        self.frames.add(self.hub)
        events.add(self.hub)
        self.intervals = ReceiveIntervals()
        self.frames.add(self.intervals)
        self.confirmation = FrameWaiters(self.frames)
        self.link = RobotLink(
            self.name,
            originator,
            cyclic,
            on_frame=self.frames.publish,
            # Late-bound: the connection watch is made below, over this link.
            on_state=lambda state, reason: self.connection.on_state(state, reason),  # noqa: PLW0108
            on_slow_target=lambda slow: self.connection.on_slow_target(slow),  # noqa: PLW0108
        )
        self.control = Control(
            self.link, store, self.frames, self.publish_event, input_only=settings.input_only
        )
        self.writes = WriteCounters(timeout_s=stream.write_timeout_ms / 1000)
        self.identity_reader = IdentityReader(self.name, settings.host, settings.tcp_port)
        """The robot's identity, read after each connection comes up (``robots.identity``)."""
        self.tags = TagBook(self.name)
        """The robot's tag names (``service.storage.tags``), loaded by ``open_state``."""
        self.alarm_store = AlarmStore(store)
        self.alarms = _alarm_engine(
            self.name,
            alarms,
            publish=self.publish_event,
            persist=self.alarm_store.submit,
            tags=lambda: self.tags.names,
        )
        """The robot's alarms (``service.alarms``), evaluated on every frame by ``watch``."""
        self.frames.add(FrameEventWatch(self.alarms, self.publish_events))
        self.connection = ConnectionWatch(
            self.name,
            self.link,
            self.frames,
            self.alarms,
            publish_event=self.publish_event,
            publish_events=self.publish_events,
            stale_after_s=self._stale_after_s,
            on_connected=lambda: self.spawn(self.identity_reader.read(), "identity"),
            on_down=self._connection_down,
        )
        """The robot's connection as watched: events, counters (``/metrics``, the doors),
        connection alarms, readiness (``robots.connection_watch``)."""
        self._tasks: list[asyncio.Task[None]] = []
        self._background: set[asyncio.Task[None]] = set()

    # ------------------------------------------------------------ lifecycle

    async def open_state(self) -> None:
        """After the store opened, before ``start``: tag names and persisted alarms."""
        await self.tags.load(self.store)
        await self.alarm_store.open()
        self.alarms.restore(await self.alarm_store.load(self.name))

    def start(self) -> None:
        """On the web loop, before the cyclic thread starts: the broadcast loop, the alarms'
        slow tick."""
        self.frames.bind_loop(asyncio.get_running_loop())
        self._tasks.append(asyncio.create_task(self.hub.run(), name=f"hub {self.name}"))
        self._tasks.append(
            asyncio.create_task(self.connection.alarm_loop(), name=f"alarms {self.name}")
        )

    async def release_control(self, reason: str) -> None:
        with contextlib.suppress(Exception):
            await self.control.drop(reason)

    async def stop(self) -> None:
        """After the cyclic thread stopped: the hub, the background work."""
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks.clear()
        if self._background:
            await asyncio.gather(*self._background, return_exceptions=True)
        await self.hub.close()
        self.confirmation.close()
        await self.alarm_store.close()

    def spawn(self, coroutine: Coroutine[Any, Any, None], name: str) -> None:
        """Run a follow-up (control release, identity read) on the web loop, tracked."""
        task = asyncio.get_running_loop().create_task(coroutine, name=f"{name} {self.name}")
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    # ------------------------------------------------------------ connection

    def _connection_down(self, state: ConnectionState) -> None:
        """On the web loop: the connection left CONNECTED (``connection`` counted it)."""
        self.intervals.reset_baseline()
        if self.control.holder is not None:
            self.spawn(self.control.drop(f"connection {state.value}"), "control-drop")

    # ------------------------------------------------------------ events

    def publish_event(self, event: Event) -> None:
        """An event of this robot on the event bus (the log, the streams, …): on the web loop."""
        self._events.publish(self.name, event)

    def publish_events(self, events: list[Event]) -> None:
        self._events.publish(self.name, *events)

    @property
    def identity(self) -> RobotIdentity | None:
        """What the robot's CIP Identity object said when last read (``None``: not yet)."""
        return self.identity_reader.identity

    @property
    def mode(self) -> str:
        """``exclusive_owner`` or ``input_only``, as the API says it."""
        return self.settings.mode.replace("-", "_")

    # ------------------------------------------------------------ answers

    async def connection_status(self, stats: ConnectionStats | None = None) -> dict[str, object]:
        """The ``ConnectionStatus`` answer of this robot as JSON-ready data (from ``stats`` when
        the caller fetched the cell's at once: ``link.stats_of``)."""
        if stats is None:
            stats = await self.link.stats()
        age = stats.last_frame_age_s
        stale = (
            stats.state is not ConnectionState.CONNECTED or age is None or age > self._stale_after_s
        )
        return {
            "state": stats.state.value,
            "reason": stats.reason,
            "robot": self.settings.host,
            "mode": self.mode,
            "rpi_ms": self.settings.rpi_ms,
            "packets_in": stats.packets_in,
            "packets_out": stats.packets_out,
            "gaps": stats.gaps,
            "duplicates": stats.duplicates,
            "late": stats.late,
            "malformed": stats.malformed,
            "interval_mean_ms": stats.interval_mean_ms,
            "interval_p99_ms": stats.interval_p99_ms,
            "interval_max_ms": stats.interval_max_ms,
            "last_frame_age_s": age,
            "stale": stale,
            "connected_since": stats.connected_since,
            "gaps_per_min": self.alarms.gaps_per_min,
            "packet_loss_high": self.alarms.packet_loss_high,
            "slow_target": stats.slow_target.words("robot") if stats.slow_target else None,
        }

    async def status(self) -> dict[str, object]:
        """The robot's connection and control as JSON-ready data (the route builds its
        ``RobotStatus`` answer from it)."""
        return {"connection": await self.connection_status(), "control": self.control.status()}

    async def hello(self, rate_hz: float | None) -> dict[str, object]:
        """The first WebSocket message of a client of this robot's stream."""
        return {
            "type": "hello",
            "robot": self.name,
            "layout_version": LAYOUT_VERSION,
            "connection": await self.connection_status(),
            "control": self.control.status(),
            "rate_hz": rate_hz,
            "time_zone": PLANT_ZONE.name,
        }
