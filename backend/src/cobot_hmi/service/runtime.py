"""Layer: service. The running service: the parts and their lifecycle, in one object.

``Service`` owns the robot link (the originator on its own thread), the broadcast hub, the
SQLite store, the users file, the sessions, control and the commander. The FastAPI app
(``service.app``) is a thin layer of routes over it.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections import Counter
from collections.abc import Coroutine
from typing import Any

from cobot_hmi.scanner.originator import ConnectionState
from cobot_hmi.service.auth import LoginThrottle, Session, Sessions
from cobot_hmi.service.commander import Commander
from cobot_hmi.service.control import Control
from cobot_hmi.service.events import Event
from cobot_hmi.service.hub import Hub
from cobot_hmi.service.link import RobotLink
from cobot_hmi.service.settings import ServiceSettings
from cobot_hmi.service.store import Store
from cobot_hmi.service.users import UsersFile

log = logging.getLogger(__name__)

_SWEEP_INTERVAL_S = 1.0


class Service:
    """Build with settings; ``start`` inside the event loop that serves HTTP; ``stop`` once."""

    def __init__(self, settings: ServiceSettings) -> None:
        self.settings = settings
        self.users = UsersFile(settings.users_path)
        self.store = Store(settings.database_path)
        self.hub = Hub(
            batch_s=settings.ws_batch_ms / 1000,
            queue_frames=settings.ws_queue_frames,
            stall_timeout_s=settings.ws_stall_timeout_s,
            frames_per_batch=round(settings.ws_batch_ms / settings.rpi_ms),
            on_events=self._store_events,
        )
        self.link = RobotLink(
            settings.originator_settings(),
            on_frame=self.hub.on_frame,
            on_state=self._on_state,
            niceness=settings.cyclic_niceness,
        )
        self.control = Control(self.link, self.store, self.hub, input_only=settings.input_only)
        self.commander = Commander(
            self.link,
            self.store,
            self.hub,
            self.control,
            timeout_s=settings.write_timeout_ms / 1000,
        )
        self.sessions = Sessions(settings.session_ttl_s, self._on_session_end)
        self.throttle = LoginThrottle(settings.login_free_attempts, settings.login_delay_max_s)
        self.logins: Counter[str] = Counter()
        self.started_at = time.time()
        self._tasks: list[asyncio.Task[None]] = []
        self._background: set[asyncio.Task[None]] = set()
        self._ws_by_session: Counter[str] = Counter()

    # ------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        await self.store.open()
        self._tasks.append(asyncio.create_task(self.hub.run(), name="hub"))
        await self.link.start()
        self._tasks.append(asyncio.create_task(self._status_loop(), name="status"))
        self._tasks.append(asyncio.create_task(self._sweep_loop(), name="sessions"))

    async def stop(self) -> None:
        """Release control, close the connection (Forward Close), stop everything else."""
        with contextlib.suppress(Exception):
            await self.control.drop("service stopping")
        await self.link.stop()
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks.clear()
        if self._background:
            await asyncio.gather(*self._background, return_exceptions=True)
        await self.hub.close()
        await self.store.close()

    def _spawn(self, coroutine: Coroutine[Any, Any, None], name: str) -> None:
        """Run a follow-up (control release) on the event loop, tracked until ``stop``."""
        task = asyncio.get_running_loop().create_task(coroutine, name=name)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    # ------------------------------------------------------------ connection

    def _on_state(self, state: ConnectionState, reason: str | None) -> None:
        """On the web loop: a connection state change from the originator."""
        self.hub.publish_event(
            {"kind": "connection", "time": time.time(), "state": state.value, "reason": reason}
        )
        if state is not ConnectionState.CONNECTED:
            self.hub.reset_interval_baseline()
            if self.control.holder is not None:
                self._spawn(self.control.drop(f"connection {state.value}"), "control-drop")

    async def connection_status(self) -> dict[str, object]:
        stats = await self.link.stats()
        age = stats.last_frame_age_s
        stale = (
            stats.state is not ConnectionState.CONNECTED
            or age is None
            or age * 1000 > self.settings.stale_after_ms
        )
        return {
            "state": stats.state.value,
            "reason": stats.reason,
            "robot": self.settings.default_robot.host,
            "mode": self.settings.default_robot.mode.replace("-", "_"),
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
        }

    async def hello(self, rate_hz: float | None) -> dict[str, object]:
        from cobot_hmi.layout import LAYOUT_VERSION

        return {
            "type": "hello",
            "layout_version": LAYOUT_VERSION,
            "connection": await self.connection_status(),
            "control": self.control.status(),
            "rate_hz": rate_hz,
        }

    async def _status_loop(self) -> None:
        while True:
            await asyncio.sleep(self.settings.status_interval_s)
            if not self.hub.clients:
                continue
            try:
                self.hub.broadcast_status({"connection": await self.connection_status()})
            except Exception:
                log.exception("status broadcast failed")

    # ------------------------------------------------------------ events

    def _store_events(self, events: list[Event]) -> None:
        for event in events:
            data = {k: v for k, v in event.items() if k not in ("kind", "time")}
            self.store.submit_event(float(event["time"]), str(event["kind"]), data)  # type: ignore[arg-type]

    # ------------------------------------------------------------ sessions

    def _on_session_end(self, session: Session, reason: str) -> None:
        if self.control.holder is not None and self.control.holder.session_id == session.id:
            self._spawn(self.control.drop(reason, session_id=session.id), "control-drop")

    async def _sweep_loop(self) -> None:
        while True:
            await asyncio.sleep(_SWEEP_INTERVAL_S)
            self.sessions.sweep()

    def websocket_opened(self, session: Session | None) -> None:
        if session is not None:
            self._ws_by_session[session.id] += 1

    def websocket_closed(self, session: Session | None) -> None:
        """The holder's last WebSocket closing releases control."""
        if session is None:
            return
        self._ws_by_session[session.id] -= 1
        if self._ws_by_session[session.id] <= 0:
            del self._ws_by_session[session.id]
            holder = self.control.holder
            if holder is not None and holder.session_id == session.id:
                self._spawn(
                    self.control.drop("holder disconnected", session_id=session.id),
                    "control-drop",
                )
