"""Layer: service (OPC UA). The OPC UA server's one contact with the service: this adapter.

Everything the server takes from the service, and every request it makes of it, goes through
``ServiceFeed``; no other module of ``cobot_hmi.opcua`` imports ``cobot_hmi.service``.

- **Frames**: a consumer of every robot's frames (``robots.frame_notifier``) that runs on the
  server's own thread: the cyclic thread's O(1) append into a bounded queue per robot (the oldest
  dropped and counted when full), drained at each monitoring tick (``sample``): only the period's
  newest frame is used, at most one RPI old (a consumer on the web loop would see it only at the
  loop's next wake, up to a WebSocket batch later). With it the link state, the command image, the
  control holder, the identity and the robot's latest health event, read as they are
  (attribute and dictionary reads; the web loop and the cyclic thread never wait for this
  thread; the health events from the health service's read-only snapshot, which the web loop
  replaces whole and never changes, ``service.health.service.LatestHealth``).
- **Users**: ``authenticate`` checks a user name and password against the service's users file
  (scrypt, on the server's thread), behind a login throttle of its own (``service.access.auth``'s
  two budgets: per client address and per user name); a refusal during a wait is immediate.
- **Writes and control**: through the one write pipeline (``service.writes.pipeline``), run on
  the service's web loop (``_on_service``); the server's coroutine awaits the outcome.
"""

from __future__ import annotations

import asyncio
import math
import secrets
import time
from collections.abc import Coroutine, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Final, TypeVar

from cobot_hmi.opcua.values import Identity, Sample
from cobot_hmi.scanner.originator import ConnectionState
from cobot_hmi.service.access.auth import LoginThrottle, Session
from cobot_hmi.service.access.users import User, UsersFile
from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.robots.frame_notifier import FrameRecord, Registration, Runs
from cobot_hmi.service.writes.pipeline import (
    WriteOutcome,
    Writer,
    release_control,
    submit_write,
    take_control,
)

if TYPE_CHECKING:
    from cobot_hmi.service.robots.robot import RobotRuntime
    from cobot_hmi.service.web.web_settings import WebSettings

QUEUE_FRAMES: Final = 256
"""Frames a robot's queue holds between two ticks (2.56 s at RPI 10 ms: a tick takes them all,
so only a server thread starved that long drops any)."""

T = TypeVar("T")

__all__ = ["ApiError", "ServiceFeed", "Session", "User", "WriteOutcome", "Writer"]
"""The service's types the server's other modules use, named through this adapter."""


class ServiceFeed:
    """See the module docstring. Built on the web loop; used from the server's thread.

    A consumer of every robot's frames (``robots.frame_notifier``) on the server's thread: each tick
    (``sample``) takes the frames queued since the last one and keeps only the newest."""

    name: Final = "opcua"
    runs: Final = Runs.THREAD
    queue_frames: Final = QUEUE_FRAMES

    def __init__(
        self,
        robots: Mapping[str, RobotRuntime],
        users: UsersFile,
        settings: WebSettings,
        web_loop: asyncio.AbstractEventLoop,
        health: Mapping[str, Mapping[str, object]] | None = None,
    ) -> None:
        """``health``: each robot's latest ``health`` event as the service keeps it (read as
        it is at each tick)."""
        self._robots = robots
        self._health = health if health is not None else {}
        self._users = users
        self._web_loop = web_loop
        self.anonymous_reads = not settings.view_requires_login
        """Whether a session without a login may read (the service's own rule for the API)."""
        self._throttle = LoginThrottle(
            settings.login_free_attempts,
            settings.login_delay_max_s,
            settings.login_user_delay_max_s,
        )
        self._registrations: dict[str, Registration] = {}
        self._newest: dict[str, FrameRecord | None] = {}
        self.logins_refused = 0

    @property
    def robot_names(self) -> list[str]:
        return list(self._robots)

    # ------------------------------------------------------------ frames

    def open(self) -> None:
        """Register with every robot's frames (on the server's thread, before the first tick)."""
        for name, robot in self._robots.items():
            self._registrations[name] = robot.frames.add(self)

    def close(self) -> None:
        for name, registration in self._registrations.items():
            self._robots[name].frames.remove(registration)
        self._registrations.clear()

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        """On the server's thread (``sample``): the newest of the frames queued since."""
        self._newest[robot] = records[-1]

    def dropped(self, name: str) -> int:
        """Frames the robot's queue lost while the web loop was late (``robots.frame_notifier``)."""
        registration = self._registrations.get(name)
        return 0 if registration is None else registration.dropped

    def keep_newest(self, name: str) -> None:
        """A tick that does not update the robot: its queued frames taken, the newest kept for
        its next ``sample`` (the queue never fills while nobody watches the robot)."""
        registration = self._registrations.get(name)
        if registration is not None:
            registration.deliver()

    def sample(self, name: str) -> Sample:
        """The robot as it is now, with the newest frame since the last sample (if any)."""
        robot = self._robots[name]
        registration = self._registrations.get(name)
        if registration is not None:
            registration.deliver()  # on_frames: the newest queued frame, if any came
        newest = self._newest.pop(name, None)
        frame, received_at = (newest.frame, newest.received_at_s) if newest else (None, 0.0)
        state = robot.link.state
        try:
            command = robot.link.command
        except AssertionError:  # the cyclic thread not started yet
            command = None
        holder = robot.control.holder
        identity = robot.identity
        return Sample(
            frame=frame,
            received_at=received_at,
            connected=state is ConnectionState.CONNECTED,
            connection_state=state.value,
            command=command,
            control_holder="" if holder is None else holder.user,
            identity=None
            if identity is None
            else Identity(
                identity.product_name, str(identity.serial_number), str(identity.product_code)
            ),
            health=self._health.get(name),
        )

    # ------------------------------------------------------------ users

    def authenticate(self, name: str, password: str, client: str) -> User | None:
        """The user if the password is theirs and no throttle wait is running, else ``None``."""
        if self._throttle.retry_after_s(name, client) > 0:
            self.logins_refused += 1
            return None
        user = self._users.authenticate(name, password)
        if user is None:
            self._throttle.failed(name, client)
            self.logins_refused += 1
            return None
        self._throttle.succeeded(name, client)
        return user

    def current(self, user: User) -> User | None:
        """``user`` as the users file has it now (``None``: removed)."""
        return self._users.user(user.name)

    @staticmethod
    def session_for(user: User) -> Session:
        """A control session of the service for one OPC UA session (it never idles out: the
        OPC UA session's end releases its control, ``drop_control``)."""
        return Session(secrets.token_urlsafe(24), user, time.time(), math.inf)

    # ------------------------------------------------------------ writes and control

    async def _on_service(self, coroutine: Coroutine[Any, Any, T]) -> T:
        """Run ``coroutine`` on the service's web loop; its result here."""
        future = asyncio.run_coroutine_threadsafe(coroutine, self._web_loop)
        return await asyncio.wrap_future(future)

    async def write(
        self, name: str, writer: Writer, body: dict[str, dict[str, object]], origin: str
    ) -> WriteOutcome:
        return await self._on_service(submit_write(self._robots[name], writer, body, origin=origin))

    async def take_control(self, name: str, writer: Writer, origin: str) -> dict[str, object]:
        """The control status; ``ApiError`` for a refusal."""
        return await self._on_service(take_control(self._robots[name], writer, origin=origin))

    async def release_control(self, name: str, writer: Writer, origin: str) -> dict[str, object]:
        return await self._on_service(release_control(self._robots[name], writer, origin=origin))

    async def drop_control(self, session: Session, reason: str) -> None:
        """The control ``session`` holds of any robot ends (its OPC UA session closed)."""

        async def drop() -> None:
            for robot in self._robots.values():
                await robot.control.drop(reason, session_id=session.id)

        await self._on_service(drop())
