"""Layer: service. The running service: the parts and their lifecycle, in one object.

``Service`` owns the robots (``service.robots.robot.RobotRuntime``: per robot its connection
handle, hub, control, write counters and connection counters), the one cyclic thread that holds
every robot's class 1 connection (``service.robots.link.CyclicLoop``), the SQLite store, the
users file, the sessions and the login throttle. The FastAPI app (``service.api.app``) is a
thin layer of routes over it.

Robots are independent: one lost, refused or restarted changes nothing of another; they share
the store, the sessions and the cyclic thread (whose death is reported and repaired, see
``link``).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections import Counter
from collections.abc import Callable, Iterable
from typing import Final

from cobot_hmi.service.access.auth import LoginThrottle, Session, Sessions
from cobot_hmi.service.access.directory import Directory
from cobot_hmi.service.access.users import User, UsersFile
from cobot_hmi.service.alarms.summary import cell_summary
from cobot_hmi.service.commissioning.service import Commissioning
from cobot_hmi.service.cycles.service import Cycles
from cobot_hmi.service.errors import UnknownRobotError
from cobot_hmi.service.events.bus import EventBus
from cobot_hmi.service.extensions import ServiceExtension
from cobot_hmi.service.health.service import Health
from cobot_hmi.service.plant_time import PLANT_ZONE
from cobot_hmi.service.recording.recorder import Recorder
from cobot_hmi.service.robots.control import Control
from cobot_hmi.service.robots.link import CyclicLoop, RobotLink, stats_of
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.robots.websocket_fanout import WebSocketFanOut
from cobot_hmi.service.service_settings import ServiceSettings
from cobot_hmi.service.storage.event_log import EventLog
from cobot_hmi.service.storage.store import Store

log = logging.getLogger(__name__)

_SWEEP_INTERVAL_S: Final = 1.0


ExtensionFactory = Callable[["Service"], Iterable[ServiceExtension]]
"""What ``cobot_hmi.composition`` hands ``Service``: the extensions for a service being built."""


def no_extensions(_service: Service) -> Iterable[ServiceExtension]:
    return ()


class Service:
    """Build with settings; ``start`` inside the event loop that serves HTTP; ``stop`` once."""

    def __init__(
        self, settings: ServiceSettings, extensions: ExtensionFactory = no_extensions
    ) -> None:
        self.settings = settings
        robot_settings = settings.cell.require_robots()
        PLANT_ZONE.use(settings.site.time_zone)  # one plant, one zone (plant_time)
        self.users = UsersFile(settings.web.users_path)
        self.store = Store(settings.web.database_path)
        self.cyclic = CyclicLoop(
            settings.cell.local_host,
            settings.cell.t2o_udp_port,
            niceness=settings.cell.cyclic_niceness,
            on_restart=self._on_cyclic_restart,
        )
        self.events = EventBus()
        """Every event of every robot, to the log, the streams and every other consumer."""
        self.events.add(EventLog(self.store))
        self.robots: dict[str, RobotRuntime] = {
            robot.name: RobotRuntime(
                robot,
                self.cyclic,
                self.store,
                self.events,
                originator=settings.cell.originator_settings(robot),
                stream=settings.stream,
                alarms=settings.alarm_limits,
            )
            for robot in robot_settings
        }
        """Every robot, in the settings' order."""
        self.cycles = Cycles(self.robots, self.store)
        """Each robot's cycle timing (``service.cycles``), where it has a trigger."""
        self.commissioning = Commissioning(self.robots, self.store)
        """Each robot's I/O checkouts and their frame watchers (``service.commissioning``)."""
        self.health = Health(settings.health, self.robots, self.store)
        """Each robot's health from its frames and cycles (``service.health``)."""
        self.events.add(self.health)  # the cycle meter's cycles reach it as events
        self.default_robot: RobotRuntime = next(iter(self.robots.values()))
        """The first robot: the one the deprecated single-robot paths answer for."""
        self.directory: Directory | None = (
            Directory(settings.directory) if settings.directory.directory_enabled else None
        )
        """Directory login (LDAP / Active Directory), when ``ldap_url`` is set."""
        self.sessions = Sessions(
            settings.web.session_ttl_s,
            self._on_session_end,
            self.users.user_for_token,
            self._user_now,
        )
        self.throttle = LoginThrottle(
            settings.web.login_free_attempts,
            settings.web.login_delay_max_s,
            settings.web.login_user_delay_max_s,
        )
        self.logins: Counter[str] = Counter()
        self.started_at = time.time()
        self._tasks: list[asyncio.Task[None]] = []
        self._ws_by_session: Counter[tuple[str, str]] = Counter()
        self.recorder: Recorder | None = (
            Recorder(settings.recording, settings.history_path, self.robots)
            if settings.recording.history
            else None
        )
        """Every frame of every robot into its recording (``service.recording.recorder``),
        unless off."""
        self.extensions: tuple[ServiceExtension, ...] = tuple(extensions(self))
        """What the composition root plugged in (``service.extensions``): the Sparkplug B edge
        node, the OPC UA server, … in the order they start."""

    def robot(self, name: str) -> RobotRuntime:
        """The robot called ``name``; ``UnknownRobotError`` naming the known ones."""
        robot = self.robots.get(name)
        if robot is None:
            raise UnknownRobotError(name, list(self.robots))
        return robot

    # The default robot's parts, for code written before there were several robots.

    @property
    def link(self) -> RobotLink:
        return self.default_robot.link

    @property
    def hub(self) -> WebSocketFanOut:
        return self.default_robot.hub

    @property
    def control(self) -> Control:
        return self.default_robot.control

    async def connection_status(self) -> dict[str, object]:
        return await self.default_robot.connection_status()

    async def hello(self, rate_hz: float | None) -> dict[str, object]:
        return await self.default_robot.hello(rate_hz)

    # ------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        self.events.bind_loop(asyncio.get_running_loop())
        await self.store.open()
        for robot in self.robots.values():
            await robot.open_state()  # tag names, persisted alarms
        await self.health.open()  # each robot's saved health state
        for robot in self.robots.values():
            robot.start()
        if self.recorder is not None:  # subscribed before the first frame can come
            await self.recorder.start()
        self.cycles.start()  # subscribed before the first frame can come
        await self.commissioning.start()  # the open checkouts watched before the first frame
        self.health.start()  # subscribed before the first frame can come
        await self.cyclic.start()
        for extension in self.extensions:  # after the links: they report what the links see
            await extension.start()
        self._tasks.append(asyncio.create_task(self._status_loop(), name="status"))
        self._tasks.append(asyncio.create_task(self._sweep_loop(), name="sessions"))
        if self.directory is not None:  # directory users' roles read again while logged in
            refresh = self.directory.refresh_loop(self.sessions.user_names)
            self._tasks.append(asyncio.create_task(refresh, name="directory"))

    async def stop(self) -> None:
        """Release control, close the connections (Forward Close), stop everything else."""
        for extension in reversed(self.extensions):  # while the robots are still up (DDEATHs)
            await extension.stop()
        await asyncio.gather(
            *(robot.release_control("service stopping") for robot in self.robots.values())
        )
        await self.cyclic.stop()
        if self.recorder is not None:  # the last frames written, the open segments closed
            await self.recorder.stop()
        await self.cycles.stop()  # the last frames measured, every cycle written
        await self.health.stop()  # the last frames and cycles fed, every robot's state saved
        await self.commissioning.stop()
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks.clear()
        for robot in self.robots.values():
            await robot.stop()
        await self.store.close()

    # ------------------------------------------------------------ health

    def _on_cyclic_restart(self, reason: str) -> None:
        """The cyclic thread died and is being restarted: an event on every robot's stream."""
        for robot in self.robots.values():
            robot.publish_event(
                {
                    "kind": "connection",
                    "time": time.time(),
                    "state": "lost",
                    "reason": f"the cyclic I/O thread died and is restarted: {reason}",
                }
            )

    def health_problems(self) -> list[str]:
        """Why the service is not healthy (``/healthz``): empty when it is.

        The cyclic thread down (dead and not yet restarted), or a robot not connected for
        longer than ``link_down_unhealthy_s`` (lost for good, refused, unreachable).
        """
        problems = []
        bound_s = self.settings.cell.link_down_unhealthy_s
        if not self.cyclic.alive:
            down = self.cyclic.down_since
            since = f" for {time.monotonic() - down:.0f} s" if down is not None else ""
            death = f" ({self.cyclic.last_death})" if self.cyclic.last_death else ""
            problems.append(f"the cyclic I/O thread is not running{since}{death}")
        for robot in self.robots.values():
            down_for_s = robot.connection.down_for_s()
            if down_for_s is not None and down_for_s > bound_s:
                state = robot.link.state.value
                reason = robot.link.reason
                problems.append(
                    f"robot {robot.name}: not connected for {down_for_s:.0f} s "
                    f"(over {bound_s:g} s): {state}{': ' + reason if reason else ''}"
                )
        return problems

    def cell_alarms(self) -> dict[str, object]:
        """``models.CellAlarmSummary``: every robot's alarms at a glance."""
        return cell_summary([robot.alarms.summary() for robot in self.robots.values()])

    async def _status_loop(self) -> None:
        while True:
            await asyncio.sleep(self.settings.stream.status_interval_s)
            if not any(robot.hub.clients for robot in self.robots.values()):
                continue
            # Once per period for every stream: a panel of one robot sees the others' alarms.
            cell_alarms = self.cell_alarms()
            watched = [robot for robot in self.robots.values() if robot.hub.clients]
            try:
                stats = await stats_of([robot.link for robot in watched])  # one hop for all
            except Exception:
                log.exception("the robots' connection statistics failed")
                continue
            for robot in watched:
                try:
                    robot.hub.broadcast_status(
                        {
                            "robot": robot.name,
                            "connection": await robot.connection_status(stats[robot.name]),
                            "cell_alarms": cell_alarms,
                        }
                    )
                except Exception:
                    log.exception("status broadcast of %s failed", robot.name)

    # ------------------------------------------------------------ sessions

    def _user_now(self, name: str) -> User | None:
        """A login's user as the users file has it now, else as the directory last read
        them (a local name is never a directory user's: routes/auth.py)."""
        user = self.users.user(name)
        if user is None and self.directory is not None:
            user = self.directory.user(name)
        return user

    def _on_session_end(self, session: Session, reason: str) -> None:
        """Control the session held is released; its WebSockets are closed by their own
        handlers (``routes_stream``: a ``Sessions.watch`` each), and each robot whose streams
        it had says so in a ``session`` event (the log and every other stream)."""
        for robot in self.robots.values():
            holder = robot.control.holder
            if holder is not None and holder.session_id == session.id:
                robot.spawn(robot.control.drop(reason, session_id=session.id), "control-drop")
            streams = self._ws_by_session.get((session.id, robot.name), 0)
            if streams > 0:
                robot.publish_event(
                    {
                        "kind": "session",
                        "time": time.time(),
                        "user": session.user.name,
                        "session": session.id,
                        "reason": reason,
                        "streams_closed": streams,
                    }
                )

    async def _sweep_loop(self) -> None:
        while True:
            await asyncio.sleep(_SWEEP_INTERVAL_S)
            self.sessions.sweep()

    def websocket_opened(self, session: Session | None, robot: RobotRuntime | None = None) -> None:
        if session is not None:
            self._ws_by_session[(session.id, (robot or self.default_robot).name)] += 1

    def websocket_closed(self, session: Session | None, robot: RobotRuntime | None = None) -> None:
        """The holder's last WebSocket of a robot closing releases its control of that robot."""
        if session is None:
            return
        robot = robot or self.default_robot
        key = (session.id, robot.name)
        self._ws_by_session[key] -= 1
        if self._ws_by_session[key] <= 0:
            del self._ws_by_session[key]
            holder = robot.control.holder
            if holder is not None and holder.session_id == session.id:
                robot.spawn(
                    robot.control.drop("holder disconnected", session_id=session.id),
                    "control-drop",
                )
