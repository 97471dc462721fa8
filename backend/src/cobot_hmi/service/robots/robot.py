"""Layer: service. One robot of the cell, everything the service keeps for it.

A ``RobotRuntime`` holds one robot's connection handle (``link``: its originator on the shared
cyclic thread), its broadcast hub, its control holder, its write counters (write confirmation and
outcome counters), its connection counters and its identity once read. Robots share only the
store, the sessions and the cyclic thread; a robot lost or refused changes nothing of another.

The identity is read with an explicit ListIdentity over the robot's TCP port (CIP Vol 2
§2-4.2) after each connection comes up, on the web loop (never on the cyclic thread); a robot
that does not answer it keeps ``identity = None``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections import Counter
from collections.abc import Callable, Coroutine, Mapping
from dataclasses import dataclass, field
from typing import Any, Final

from cobot_hmi.enip.errors import EnipError
from cobot_hmi.enip.identity import IdentityInfo
from cobot_hmi.layout import LAYOUT_VERSION
from cobot_hmi.scanner.originator import ConnectionState, ConnectionStats, OriginatorSettings
from cobot_hmi.scanner.session import EnipSession, SessionError
from cobot_hmi.scanner.t2o_pace import SlowTarget
from cobot_hmi.service.alarms.engine import TICK_S, AlarmEngine, UserAlarm
from cobot_hmi.service.alarms.persistence import AlarmChange, AlarmStore
from cobot_hmi.service.alarms.settings import AlarmLimitSettings
from cobot_hmi.service.events.bus import EventBus
from cobot_hmi.service.events.text import Event
from cobot_hmi.service.plant_time import PLANT_ZONE
from cobot_hmi.service.robots.confirmation import FrameWaiters
from cobot_hmi.service.robots.control import Control
from cobot_hmi.service.robots.frame_notifier import FrameNotifier
from cobot_hmi.service.robots.intervals import ReceiveIntervals
from cobot_hmi.service.robots.link import CyclicLoop, RobotLink
from cobot_hmi.service.robots.settings import RobotSettings
from cobot_hmi.service.robots.watch import FrameEventWatch
from cobot_hmi.service.robots.websocket_fanout import WebSocketFanOut
from cobot_hmi.service.storage.store import Store
from cobot_hmi.service.storage.tags import TagBook
from cobot_hmi.service.web.settings import WebSettings

log = logging.getLogger(__name__)

IDENTITY_TIMEOUT_S: Final = 3.0


@dataclass
class WriteCounters:
    """A robot's writes: how long a write waits for the robot's confirmation, and how many
    ended in each outcome (``confirmed``, ``refused``, ``timeout``, …) for /metrics; the write
    pipeline (``service.writes.pipeline``) counts into them."""

    timeout_s: float
    outcomes: Counter[str] = field(default_factory=Counter)


@dataclass(frozen=True, slots=True)
class RobotIdentity:
    """What the robot's CIP Identity object says (Vol 1 §5A-2), read by ListIdentity."""

    vendor_id: int
    device_type: int
    product_code: int
    revision: str
    """major.minor"""
    serial_number: int
    product_name: str

    @classmethod
    def from_info(cls, info: IdentityInfo) -> RobotIdentity:
        return cls(
            vendor_id=info.vendor_id,
            device_type=info.device_type,
            product_code=info.product_code,
            revision=info.revision,
            serial_number=info.serial_number,
            product_name=info.product_name,
        )

    def to_json(self) -> dict[str, object]:
        return {
            "vendor_id": self.vendor_id,
            "device_type": self.device_type,
            "product_code": self.product_code,
            "revision": self.revision,
            "serial_number": self.serial_number,
            "product_name": self.product_name,
        }


async def read_identity(
    host: str, tcp_port: int, timeout_s: float = IDENTITY_TIMEOUT_S
) -> RobotIdentity:
    """ListIdentity over TCP (a session of its own); ``OSError``/``SessionError``/``EnipError``."""
    session = EnipSession(host, tcp_port, timeout_s)
    try:
        await session.open()
        return RobotIdentity.from_info(await session.list_identity())
    finally:
        await session.close()


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
    """One robot: connection handle, hub, control, write counters, identity.

    Given what it uses and no more: its own settings, its connection's (``originator``), the
    web service's stream and write limits (``web``) and the alarm settings (``alarms``)."""

    def __init__(
        self,
        settings: RobotSettings,
        cyclic: CyclicLoop,
        store: Store,
        events: EventBus,
        *,
        originator: OriginatorSettings,
        web: WebSettings,
        alarms: AlarmLimitSettings,
    ) -> None:
        self.name = settings.name
        self.settings = settings
        self.store = store
        self._stale_after_s = web.stale_after_ms / 1000
        self._events = events
        self.frames = FrameNotifier(
            self.name,
            frames_per_wake=max(1, round(web.ws_batch_ms / settings.rpi_ms)),
        )
        """Every frame of the robot, published once, to every consumer
        (``robots.frame_notifier``)."""
        self.hub = WebSocketFanOut(
            robot=self.name,
            batch_s=web.ws_batch_ms / 1000,
            client_queue_frames=web.ws_queue_frames,
            stall_timeout_s=web.ws_stall_timeout_s,
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
            on_state=self._on_state,
            on_slow_target=self._on_slow_target,
        )
        self.control = Control(
            self.link, store, self.frames, self.publish_event, input_only=settings.input_only
        )
        self.writes = WriteCounters(timeout_s=web.write_timeout_ms / 1000)
        self.identity: RobotIdentity | None = None
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
        # Counters (``/metrics``).
        self.connects = 0
        """Times the connection came up."""
        self.losses = 0
        """Times it went from connected to lost."""
        self.down_since: float | None = time.monotonic()
        """``time.monotonic()`` since the robot is not connected (``None``: connected)."""
        self._slow_target: SlowTarget | None = None
        """The last slowness of T→O reported (for the words once it clears)."""
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
        self._tasks.append(asyncio.create_task(self._alarm_loop(), name=f"alarms {self.name}"))

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

    def _on_state(self, state: ConnectionState, reason: str | None) -> None:
        """On the web loop: a connection state change of this robot only."""
        self.publish_event(
            {"kind": "connection", "time": time.time(), "state": state.value, "reason": reason}
        )
        for event in self._connection_alarms(time.time(), time.monotonic()):
            self.publish_event(event)
        if state is ConnectionState.CONNECTED:
            self.connects += 1
            self.down_since = None
            self.spawn(self._read_identity(), "identity")
            return
        if self.down_since is None:
            self.down_since = time.monotonic()
            if state is ConnectionState.LOST:
                self.losses += 1
        self.intervals.reset_baseline()
        if self.control.holder is not None:
            self.spawn(self.control.drop(f"connection {state.value}"), "control-drop")

    def _on_slow_target(self, slow: SlowTarget | None) -> None:
        """On the web loop: the robot sends T→O slower than it granted, or keeps its grant
        again (``scanner.t2o_pace``): a connection event in words, once each."""
        if slow is not None:
            self._slow_target = slow
            reason = slow.words("robot")
        elif self._slow_target is not None:
            reason = self._slow_target.kept_words("robot")
        else:
            return
        self.publish_event(
            {"kind": "connection", "time": time.time(), "state": "connected", "reason": reason}
        )

    async def _read_identity(self) -> None:
        try:
            identity = await read_identity(self.settings.host, self.settings.tcp_port)
        except (OSError, SessionError, EnipError, TimeoutError) as error:
            log.info("%s: no identity (ListIdentity): %s", self.name, error)
            return
        if identity != self.identity:
            log.info("%s: %s, revision %s", self.name, identity.product_name, identity.revision)
        self.identity = identity

    # ------------------------------------------------------------ alarms (slow part)

    def _connection_alarms(self, now_s: float, monotonic_s: float) -> list[dict[str, object]]:
        state = self.link.state
        latest = self.frames.latest
        return self.alarms.connection(
            connected=state is ConnectionState.CONNECTED,
            refused=state is ConnectionState.REFUSED,
            reason=self.link.reason,
            frame_age_s=None if latest is None else max(0.0, now_s - latest.received_at_s),
            stale_after_s=self._stale_after_s,
            now_s=now_s,
            monotonic_s=monotonic_s,
        )

    async def _alarm_loop(self) -> None:
        while True:
            await asyncio.sleep(TICK_S)
            try:
                await self._alarm_tick()
            except Exception:  # a bug here must not end the alarms' tick
                log.exception("%s: alarm tick failed", self.name)

    async def _alarm_tick(self) -> None:
        now_s, monotonic_s = time.time(), time.monotonic()
        events = self._connection_alarms(now_s, monotonic_s)
        gaps = self.link.gaps if self.link.state is ConnectionState.CONNECTED else None
        events += self.alarms.gaps(gaps, now_s=now_s, monotonic_s=monotonic_s)
        events += self.alarms.expire_shelving(now_s)
        self.publish_events(events)

    # ------------------------------------------------------------ events

    def publish_event(self, event: Event) -> None:
        """An event of this robot on the event bus (the log, the streams, …): on the web loop."""
        self._events.publish(self.name, event)

    def publish_events(self, events: list[Event]) -> None:
        self._events.publish(self.name, *events)

    @property
    def mode(self) -> str:
        """``exclusive_owner`` or ``input_only``, as the API says it."""
        return self.settings.mode.replace("-", "_")

    def down_for_s(self) -> float | None:
        """How long the robot has not been connected (``None``: connected)."""
        since = self.down_since
        return None if since is None else time.monotonic() - since

    def ready(self) -> tuple[bool, str | None]:
        """Connected (and frames coming), or why not: ``/readyz``."""
        state = self.link.state
        if state is not ConnectionState.CONNECTED:
            reason = self.link.reason
            return False, f"{state.value}{': ' + reason if reason else ''}"
        return True, None

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
