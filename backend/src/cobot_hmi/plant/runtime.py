"""Layer: plant (a door above the service). The running plant: the host application fed by the
MQTT client's thread on the web event loop (through a bounded inbox, in batches, in arrival
order: a full inbox holds the client's thread, nothing is dropped), its rebirth requests
published, what it receives handed to the recorder (flushed on a worker thread), and the
service's login pieces (users file, sessions, login throttle, directory) that the plant's web
API shares with ``serve``'s through the service's own auth routes.
"""

from __future__ import annotations

import asyncio
import contextlib
import gc
import logging
import threading
import time
from collections import Counter, deque
from typing import Final

from cobot_hmi.plant.client import FailoverClient
from cobot_hmi.plant.host import HostApplication
from cobot_hmi.plant.plant_settings import PlantSettings
from cobot_hmi.plant.recorder import FLUSH_S, PlantRecorder
from cobot_hmi.service.access.auth import LoginThrottle, Session, Sessions
from cobot_hmi.service.access.directory import Directory
from cobot_hmi.service.access.users import User, UsersFile
from cobot_hmi.service.storage.store import Store
from cobot_hmi.sparkplug.mqtt_client import BrokerAddress, ClientOptions

log = logging.getLogger(__name__)

_SWEEP_S: Final = 1.0
INBOX_LIMIT: Final = 20_000
"""Messages received and not yet handled, at most (about 6 s of a 500-robot plant's DDATA, some
15 MiB): past it the client's thread waits, and the brokers hold the rest. Not less: a broker
keeps little for a slow QoS 0 subscriber (Mosquitto about 1000 messages) and drops the rest,
each drop a seq gap, each gap a rebirth of the whole node, several times the work of its
DDATA; a hiccup of the machine of a few seconds should cost none."""
INBOX_WAIT_S: Final = 0.5
"""The client's thread, waiting for room, looks again this often whether the plant stops."""
BATCH: Final = 500
"""Messages handled in one turn of the event loop (about 50 ms at 0.1 ms each)."""
MODEL_SETTLED_S: Final = 10.0
"""The model no new series for this long: what it holds is set aside from the garbage
collector's full collections (``_set_model_aside``)."""


class PlantRuntime:
    """Build with the settings; ``start`` inside the event loop that serves HTTP; ``stop`` once.
    Its login attributes (``users``, ``sessions``, ``throttle``, ``logins``, ``directory``,
    ``store``, ``settings``) are the ones the service's auth routes read."""

    def __init__(self, settings: PlantSettings) -> None:
        self.settings = settings
        self.users = UsersFile(settings.web.users_path)
        self.store = Store(settings.web.database_path)
        self.directory: Directory | None = (
            Directory(settings.directory) if settings.directory.directory_enabled else None
        )
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
        self.host = HostApplication(
            settings.plant.plant_host_id,
            frozenset(settings.plant.plant_groups),
            settings.plant.plant_rebirth_interval_s,
        )
        self.recorder = PlantRecorder(settings.plant_history_path, self.host.series)
        options = [
            ClientOptions(
                BrokerAddress.parse(url),
                f"{settings.plant.plant_host_id}",
                settings.plant.mqtt_user,
                settings.plant.mqtt_password,
                settings.plant.mqtt_ca_file,
            )
            for url in settings.plant.mqtt_urls
        ]
        self.client = FailoverClient(
            options,
            settings.plant.plant_host_id,
            self.host.subscriptions,
            self._from_client,
            self._connected,
        )
        self.started_at = time.time()
        self.messages = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._inbox: deque[tuple[str, bytes, float]] = deque()
        """Messages from the client's thread, not yet handled on the event loop."""
        self._room = threading.Condition()
        """Guards the inbox; the client's thread waits on it while the inbox is full."""
        self._wake_pending = False
        self._closing = False
        self.inbox_full = 0
        """Times the client's thread waited for room (the plant behind its brokers)."""
        self._series_seen = (0, 0.0)
        """How many series the model had, since when (``time.monotonic``)."""
        self._series_aside = 0
        self._tasks: list[asyncio.Task[None]] = []

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        await self.store.open()
        self._tasks.append(asyncio.create_task(self._flush_loop(), name="plant history"))
        self._tasks.append(asyncio.create_task(self._sweep_loop(), name="plant sessions"))
        if self.directory is not None:
            refresh = self.directory.refresh_loop(self.sessions.user_names)
            self._tasks.append(asyncio.create_task(refresh, name="directory"))
        self.client.start()

    async def stop(self) -> None:
        with self._room:  # a client's thread waiting for room lets go
            self._closing = True
            self._room.notify_all()
        await asyncio.to_thread(self.client.stop)
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks.clear()
        await asyncio.to_thread(self.recorder.flush)  # the last values written
        await self.store.close()

    # ------------------------------------------------------------ messages

    def _from_client(self, topic: str, data: bytes) -> None:
        """On the client's thread: into the inbox, with the time it was received; the event
        loop woken once for all that come before it drains them. A full inbox holds this
        thread (it reads no more from the broker, whose QoS rules then hold or drop for the
        plant: a lost QoS 0 DDATA is a seq gap the host answers with a rebirth) until the loop
        has made room: nothing is dropped here, and the memory stays bounded."""
        loop = self._loop
        if loop is None or loop.is_closed():
            return
        received_s = time.time()
        with self._room:
            while len(self._inbox) >= INBOX_LIMIT:
                if self._closing or loop.is_closed():
                    return
                self.inbox_full += 1
                self._room.wait(INBOX_WAIT_S)
            self._inbox.append((topic, data, received_s))
            if self._wake_pending:
                return
            self._wake_pending = True
        with contextlib.suppress(RuntimeError):  # the loop closed meanwhile: the plant stops
            loop.call_soon_threadsafe(self._drain)

    def _drain(self) -> None:
        """On the event loop: up to ``BATCH`` messages, in arrival order; the rest on the next
        turn, so that the web requests are answered in between."""
        with self._room:
            inbox = self._inbox
            batch = [inbox.popleft() for _ in range(min(len(inbox), BATCH))]
            more = bool(inbox)
            self._wake_pending = more
            self._room.notify()
        for topic, data, received_s in batch:
            try:
                self._handle(topic, data, received_s)
            except Exception:  # one message's failure never stalls the others
                log.exception("plant: message on %s not handled", topic)
        if more and self._loop is not None and not self._loop.is_closed():
            self._loop.call_soon(self._drain)

    def _handle(self, topic: str, data: bytes, received_s: float) -> None:
        self.messages += 1
        try:
            answer = self.host.on_message(topic, data, received_s)
        except Exception:  # one bad message never stops the plant
            log.exception("plant: message on %s not handled", topic)
            return
        for out in answer.publish:
            self.client.publish(out.topic, out.payload, out.qos, out.retain)
        if answer.columns.times_ms:
            self.recorder.add_columns(answer.columns)

    def _seen_until_s(self) -> float:
        """Every message received before this time has been handled (on the event loop)."""
        with self._room:
            return self._inbox[0][2] if self._inbox else time.time()

    def _connected(self, url: str) -> None:
        """On the client's thread: connected and subscribed (the STATE birth went out)."""
        log.info("plant: connected to %s as host %s", url, self.settings.plant.plant_host_id)
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._reconnected, time.time())

    def _reconnected(self, now_s: float) -> None:
        """Every node the host knew alive asked for a rebirth (none on the first connection):
        what they published while the plant had no connection is lost to it."""
        for out in self.host.on_reconnect(now_s):
            self.client.publish(out.topic, out.payload, out.qos, out.retain)

    async def _flush_loop(self) -> None:
        while True:
            await asyncio.sleep(FLUSH_S)
            try:
                await asyncio.to_thread(self.recorder.flush)
            except Exception:
                log.exception("plant history: flush failed")

    # ------------------------------------------------------------ sessions

    def _user_now(self, name: str) -> User | None:
        user = self.users.user(name)
        if user is None and self.directory is not None:
            user = self.directory.user(name)
        return user

    def _on_session_end(self, session: Session, reason: str) -> None:
        log.info("plant: session of %s ended (%s)", session.user.name, reason)

    def _set_model_aside(self, now_s: float) -> None:
        """Once the model has settled (no new series for ``MODEL_SETTLED_S``), everything the
        process holds is frozen out of the garbage collector's full collections (after one last
        collection, so that no garbage is kept): a 500-robot model is some 400 000 objects,
        which every full collection walked, holding the event loop for 0.2 to 0.8 s, a few
        times a minute (bench/plant). What is frozen is still freed when no longer referenced;
        only a cycle among frozen objects is not collected, and the model's live values have
        none. Again each time the model has grown (new series) and settled."""
        count = len(self.host.series.names)
        if count != self._series_seen[0]:
            self._series_seen = (count, now_s)
        elif count != self._series_aside and now_s - self._series_seen[1] >= MODEL_SETTLED_S:
            self._series_aside = count
            gc.collect()
            gc.freeze()

    async def _sweep_loop(self) -> None:
        while True:
            await asyncio.sleep(_SWEEP_S)
            self.sessions.sweep()
            self._set_model_aside(time.monotonic())
            # Rebirth requests the host's rate limit held, once it allows them, and those
            # unanswered once everything received long enough after them has been handled.
            for out in self.host.due(time.time(), self._seen_until_s()):
                self.client.publish(out.topic, out.payload, out.qos, out.retain)
