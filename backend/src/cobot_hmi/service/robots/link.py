"""Layer: service. The class 1 connections to the robots, on one thread and event loop of their
own, supervised.

Every robot's originator (``cobot_hmi.scanner.originator``) runs on one private asyncio loop in
one thread (``CyclicLoop``), as a PLC's I/O task holds all of its connections, and they share
one ``IoPort``: all robots' T→O arrive on one UDP 2222 socket of the service's address and are
told apart by connection ID (a second socket on 2222 of one address cannot work). Web work
(serializing frames, WebSocket sends, HTTP parsing, SQLite) never delays a T→O receive or an
O→T send by more than a GIL hand-over: the cyclic timing does not depend on how many clients
watch.

Each robot has a ``RobotLink``, its handle on its originator: everything the web side asks of
it goes through ``run_coroutine_threadsafe``; plain attribute reads (``state``, ``run``,
``command``) are single loads under the GIL. The frame callback goes straight to
``FrameNotifier.publish`` (``robots.frame_notifier``) on the cyclic thread (it is O(1), with no
lock: this thread is the one producer of every robot's frames, and a restarted thread starts only
once the one before it has ended); state changes are handed to the web loop. One robot lost or
refused is one originator's business: the others run on.

Supervision: the cyclic thread ending while the service has not asked it to (an exception out
of its loop, a bug) is never silent: it is logged, every robot's link reports LOST with the
reason (so control ends), ``on_restart`` tells the service (an event and a metric), and the
thread is started again after a short, growing delay with a new port and new originators.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import functools
import logging
import os
import threading
import time
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import replace
from typing import Any, Final, TypeVar

from cobot_hmi.codec import CommandImage, Frame
from cobot_hmi.eventloop import precise_event_loop
from cobot_hmi.scanner.io_port import IoPort
from cobot_hmi.scanner.originator import (
    ConnectionState,
    ConnectionStats,
    NotConnectedError,
    Originator,
    OriginatorSettings,
)
from cobot_hmi.scanner.t2o_pace import SlowTarget

log = logging.getLogger(__name__)

_T = TypeVar("_T")

_JOIN_TIMEOUT_S: Final = 10.0
"""How long stopping waits for the cyclic thread (Forward Closes take at most ~2 s)."""
_SALVAGE_TIMEOUT_S: Final = 5.0
"""How long the Forward Closes after a death of the thread may take, all together."""
RESTART_DELAY_S: Final = 0.5
"""First wait before the cyclic thread is started again; doubles up to ``RESTART_DELAY_MAX_S``
while it keeps dying at once (no hot loop), back to this after a run of a minute."""
RESTART_DELAY_MAX_S: Final = 10.0
_STABLE_RUN_S: Final = 60.0

FrameCallback = Callable[[Frame, bytes, float, int], None]
"""``(frame, payload, received_at, t2o_sequence)``: the originator's ``on_frame``: the frame, the
T→O payload it was decoded from, the kernel's receive time, the packet's wire sequence number."""
StateCallback = Callable[[ConnectionState, str | None], None]
SlowTargetCallback = Callable[[SlowTarget | None], None]
"""The originator's ``on_slow_target``, handed to the web loop."""


class CyclicLoop:
    """The one cyclic thread: its event loop, the shared UDP port and every robot's originator.

    ``start`` and ``stop`` once each, from the web loop; links attach before ``start``.
    """

    def __init__(
        self,
        local_host: str,
        udp_port: int,
        *,
        niceness: int = 0,
        on_restart: Callable[[str], None] | None = None,
    ) -> None:
        self.local_host = local_host
        self.udp_port = udp_port
        self.niceness = niceness
        self._on_restart = on_restart
        self.links: list[RobotLink] = []
        self.restarts = 0
        """How often the thread died and was started again."""
        self.last_death: str | None = None
        """Why the thread last died (``None``: never)."""
        self.down_since: float | None = None
        """``time.monotonic()`` since the thread is down (``None``: running or never started)."""
        self._web_loop: asyncio.AbstractEventLoop | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._port: IoPort | None = None
        self._originators: list[Originator] = []
        self._stopping: asyncio.Event | None = None
        self._ended: concurrent.futures.Future[str | None] = concurrent.futures.Future()
        self._death: asyncio.Future[str | None] | None = None
        """On the web loop: done (with the reason) once the current thread has ended."""
        self._stop_requested = False
        self._supervisor: asyncio.Task[None] | None = None
        self._started_at = 0.0

    def attach(self, link: RobotLink) -> None:
        if self._thread is not None:
            raise RuntimeError("attach every link before CyclicLoop.start()")
        self.links.append(link)

    # ------------------------------------------------------------ state

    @property
    def alive(self) -> bool:
        """The thread runs its loop (False while it is being restarted, and after ``stop``)."""
        thread = self._thread
        return thread is not None and thread.is_alive() and not self._ended.done()

    @property
    def loop(self) -> asyncio.AbstractEventLoop | None:
        return self._loop

    @property
    def thread_id(self) -> int | None:
        thread = self._thread
        return thread.ident if thread is not None else None

    # ------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        """Start the thread and every originator (which then connect and reconnect themselves)."""
        self._web_loop = asyncio.get_running_loop()
        await self._start_thread()
        self._supervisor = asyncio.create_task(self._supervise(), name="cyclic-supervisor")

    async def _start_thread(self) -> None:
        started: concurrent.futures.Future[None] = concurrent.futures.Future()
        self._ended = concurrent.futures.Future()
        assert self._web_loop is not None
        self._death = self._web_loop.create_future()
        self._started_at = time.monotonic()
        thread = threading.Thread(
            target=self._thread_main,
            args=(started, self._ended, self._death),
            name="cyclic-io",
            daemon=True,
        )
        self._thread = thread
        thread.start()
        await asyncio.wrap_future(started)
        self.down_since = None

    def _thread_main(
        self,
        started: concurrent.futures.Future[None],
        ended: concurrent.futures.Future[str | None],
        death: asyncio.Future[str | None],
    ) -> None:
        reason: str | None = "the cyclic loop ended by itself"
        try:
            if self.niceness:
                # Linux schedules threads one by one: this raises (or lowers) only the cyclic
                # thread, so a busy host delays its wake-ups less. Not permitted: keep going.
                try:
                    os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), self.niceness)
                except OSError as error:
                    log.warning(
                        "cyclic thread priority unchanged (nice %d): %s", self.niceness, error
                    )
            # Sub-millisecond timers for the O→T schedule (see ``cobot_hmi.eventloop``).
            loop = precise_event_loop()
            self._loop = loop
            try:
                loop.run_until_complete(self._main(started))
                if self._stop_requested:
                    reason = None
            except BaseException:
                # Before the port closes: each robot's Forward Close and session end, so the
                # robots free their exclusive-owner slot for the restarted thread at once.
                with contextlib.suppress(BaseException):
                    self._salvage(loop)
                raise
            finally:
                with contextlib.suppress(BaseException):
                    self._close_port()
                with contextlib.suppress(BaseException):
                    loop.close()
        except BaseException as error:  # whatever ends the thread is reported, never swallowed
            reason = f"{type(error).__name__}: {error}" if str(error) else type(error).__name__
            if not started.done():
                started.set_exception(RuntimeError(f"the cyclic thread failed to start: {reason}"))
        finally:
            if not started.done():
                started.set_exception(RuntimeError(f"the cyclic thread ended: {reason}"))
            if not ended.done():
                ended.set_result(reason)
            web_loop = self._web_loop
            if web_loop is not None and not web_loop.is_closed():
                with contextlib.suppress(RuntimeError):
                    web_loop.call_soon_threadsafe(_settle, death, reason)

    def _salvage(self, loop: asyncio.AbstractEventLoop) -> None:
        """After the loop died: stop the originators (bounded) and end every task left. The
        loop may be what broke (its selector): then nothing more runs on it, and the coroutine
        that never started is closed rather than left for the garbage collector to warn about."""

        async def stop_all() -> None:
            async with asyncio.timeout(_SALVAGE_TIMEOUT_S):
                await asyncio.gather(
                    *(originator.stop() for originator in self._originators),
                    return_exceptions=True,
                )

        stopping = stop_all()
        try:
            loop.run_until_complete(stopping)
        except BaseException:
            stopping.close()
            raise
        finally:
            tasks = asyncio.all_tasks(loop)
            for task in tasks:
                task.cancel()
            if tasks:
                loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))

    def _close_port(self) -> None:
        port, self._port = self._port, None
        if port is not None:
            port.close()

    async def _main(self, started: concurrent.futures.Future[None]) -> None:
        self._stopping = asyncio.Event()
        port = IoPort(self.local_host, self.udp_port)
        self._port = port
        originators = [link._new_originator(port) for link in self.links]
        self._originators = originators
        try:
            for originator in originators:
                await originator.start()
        except BaseException as error:
            started.set_exception(error)
            raise
        started.set_result(None)
        await self._stopping.wait()
        # Forward Close and UnRegisterSession for every robot at once (each bounded).
        results = await asyncio.gather(
            *(originator.stop() for originator in originators), return_exceptions=True
        )
        for link, result in zip(self.links, results, strict=True):
            if isinstance(result, BaseException):
                log.error("stopping the originator of %s failed: %r", link.name, result)

    async def _supervise(self) -> None:
        """On the web loop: restart the thread each time it dies (see the module docstring)."""
        delay_s = RESTART_DELAY_S
        while True:
            assert self._death is not None
            reason = await asyncio.shield(self._death)
            if self._stop_requested:
                return
            reason = reason or "the cyclic thread ended"
            self.restarts += 1
            self.last_death = reason
            self.down_since = time.monotonic()
            log.error("the cyclic I/O thread died (%s): restarting it in %.1f s", reason, delay_s)
            for link in self.links:
                link._thread_died(reason)
            if self._on_restart is not None:
                try:
                    self._on_restart(reason)
                except Exception:
                    log.exception("reporting the cyclic thread's restart failed")
            if time.monotonic() - self._started_at > _STABLE_RUN_S:
                delay_s = RESTART_DELAY_S
            await asyncio.sleep(delay_s)
            delay_s = min(delay_s * 2, RESTART_DELAY_MAX_S)
            if self._stop_requested:
                return
            try:
                await self._start_thread()
            except Exception as error:  # the next round of the loop waits for its end
                log.error("restarting the cyclic I/O thread failed: %s", error)
            else:
                log.warning("the cyclic I/O thread runs again (restart %d)", self.restarts)

    async def stop(self) -> None:
        """Close every connection (Forward Close) and end the thread. Idempotent."""
        self._stop_requested = True
        supervisor, self._supervisor = self._supervisor, None
        if supervisor is not None:
            supervisor.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await supervisor
        thread, loop, stopping = self._thread, self._loop, self._stopping
        if thread is None:
            return
        self._thread = None
        if loop is not None and stopping is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(stopping.set)
        await asyncio.get_running_loop().run_in_executor(None, thread.join, _JOIN_TIMEOUT_S)
        if thread.is_alive():  # a daemon thread: it cannot keep the process alive
            log.error("the cyclic thread did not end within %.0f s", _JOIN_TIMEOUT_S)

    # ------------------------------------------------------------ calls on the cyclic loop

    async def pump_counters(self) -> dict[str, int]:
        """The shared UDP port's cyclic pump counters (``UdpEndpoint.counters``; since the
        thread last started: a restart opens a new port), read on the cyclic thread, where the
        port closes. Empty while the thread is down."""

        async def read() -> dict[str, int]:
            port = self._port
            return port.udp.counters() if port is not None and port.is_open else {}

        try:
            return await self.call(read)
        except NotConnectedError:
            return {}

    async def call(self, make: Callable[[], Awaitable[_T]]) -> _T:
        """Run ``make()`` on the cyclic loop; ``NotConnectedError`` while the thread is down
        (also when it dies during the call: the answer would never come)."""
        loop, death = self._loop, self._death
        if loop is None or loop.is_closed() or death is None or death.done():
            raise NotConnectedError("the cyclic I/O thread is not running")

        async def call() -> _T:
            return await make()

        try:
            future = asyncio.run_coroutine_threadsafe(call(), loop)
        except RuntimeError:  # the loop closed in between
            raise NotConnectedError("the cyclic I/O thread is not running") from None
        answer = asyncio.wrap_future(future)
        # ``asyncio.wait`` leaves ``death`` as it is (shared by every call: never cancelled).
        waiting: set[asyncio.Future[Any]] = {answer, death}
        done, _ = await asyncio.wait(waiting, return_when=asyncio.FIRST_COMPLETED)
        if answer in done:
            return answer.result()
        answer.cancel()
        raise NotConnectedError(f"the cyclic I/O thread died: {death.result()}")


async def stats_of(links: Sequence[RobotLink]) -> dict[str, ConnectionStats]:
    """Every link's connection statistics by name, computed on the cyclic thread (a consistent
    snapshot: its interval window changes there) in ONE hop for all of them: the status
    broadcast and each /metrics scrape ask for the whole cell, and a hop per robot woke both
    loops 16 times for 16 robots. A dead thread's counters are plain reads."""
    if not links:
        return {}
    cyclic = links[0].cyclic

    async def every() -> dict[str, ConnectionStats]:
        return {link.name: link.originator.stats() for link in links}

    try:
        raw = await cyclic.call(every)
    except NotConnectedError:
        raw = {link.name: link.originator.stats() for link in links}
    return {link.name: link._marked(raw[link.name]) for link in links}


def _settle(future: asyncio.Future[str | None], reason: str | None) -> None:
    if not future.done():
        future.set_result(reason)


class RobotLink:
    """One robot's class 1 connection: its originator on the shared cyclic loop."""

    def __init__(
        self,
        name: str,
        settings: OriginatorSettings,
        cyclic: CyclicLoop,
        *,
        on_frame: FrameCallback,
        on_state: StateCallback,
        on_slow_target: SlowTargetCallback | None = None,
    ) -> None:
        self.name = name
        self.settings = settings
        self.cyclic = cyclic
        self._on_frame = on_frame
        self._on_state = on_state
        self._on_slow_target = on_slow_target
        self._originator: Originator | None = None
        self._dead: str | None = None
        """Why the cyclic thread that ran our originator died (until a new one runs)."""
        cyclic.attach(self)

    def _new_originator(self, port: IoPort) -> Originator:
        """On the cyclic loop, at each (re)start of its thread."""
        originator = Originator(
            self.settings,
            on_frame=self._on_frame,
            on_state=self._state_from_thread,
            on_slow_target=self._slow_target_from_thread,
            io_port=port,
        )
        self._originator = originator
        self._dead = None
        return originator

    def _state_from_thread(self, state: ConnectionState, reason: str | None) -> None:
        self._to_web_loop(state, reason)

    def _slow_target_from_thread(self, slow: SlowTarget | None) -> None:
        loop = self.cyclic._web_loop
        if self._on_slow_target is not None and loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(self._on_slow_target, slow)

    def _to_web_loop(self, state: ConnectionState, reason: str | None) -> None:
        loop = self.cyclic._web_loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(self._on_state, state, reason)

    def _thread_died(self, reason: str) -> None:
        """On the web loop: our originator's thread is gone; report the loss."""
        self._dead = f"the cyclic I/O thread died: {reason}"
        self._on_state(ConnectionState.LOST, self._dead)

    # ------------------------------------------------------------ reads

    @property
    def originator(self) -> Originator:
        assert self._originator is not None, "CyclicLoop.start() first"
        return self._originator

    @property
    def gaps(self) -> int:
        """T→O packets missed so far: one counter read (a single load under the GIL), where
        ``stats`` computes every figure on the cyclic thread; the alarms' tick reads this."""
        return self._originator.gaps if self._originator is not None else 0

    @property
    def state(self) -> ConnectionState:
        if self._dead is not None:
            return ConnectionState.LOST
        originator = self._originator
        return originator.state if originator is not None else ConnectionState.IDLE

    @property
    def reason(self) -> str | None:
        if self._dead is not None:
            return self._dead
        originator = self._originator
        return originator.reason if originator is not None else None

    @property
    def run(self) -> bool:
        originator = self._originator
        return originator.run and self._dead is None if originator is not None else False

    @property
    def command(self) -> CommandImage:
        return self.originator.command

    @property
    def latest(self) -> tuple[Frame, float] | None:
        originator = self._originator
        return originator.latest if originator is not None else None

    @property
    def t2o_api_us(self) -> int | None:
        """The open connection's T→O packet interval (None between connections): read from the
        health thread (``service.health.producer_clock``)."""
        originator = self._originator
        return originator.t2o_api_us if originator is not None else None

    # ------------------------------------------------------------ calls on the cyclic loop

    async def _call_sync(self, function: Callable[[], _T]) -> _T:
        async def call() -> _T:
            return function()

        return await self.cyclic.call(call)

    async def stats(self) -> ConnectionStats:
        return (await stats_of((self,)))[self.name]

    def _marked(self, stats: ConnectionStats) -> ConnectionStats:
        """``stats`` as the service reports them: lost while our thread is dead."""
        if self._dead is not None:
            return _with_state(stats, ConnectionState.LOST, self._dead)
        return stats

    async def set_run(self, run: bool) -> None:
        """Run or idle; raises the originator's ``ReadOnlyError`` / ``NotConnectedError``."""
        await self._call_sync(lambda: self.originator.set_run(run))

    async def set_command(self, image: CommandImage) -> int:
        """Replace the O→T image; the packets_out count after which it is on the wire."""
        return await self._call_sync(lambda: self.originator.set_command(image))

    async def wait_sent(self, packets_out: int, timeout_s: float) -> bool:
        try:
            return await self.cyclic.call(lambda: self.originator.wait_sent(packets_out, timeout_s))
        except NotConnectedError:
            return False

    async def _wait_connected_on_loop(self, timeout_s: float) -> bool:
        return await self.originator.wait_connected(timeout_s)

    async def wait_connected(self, timeout_s: float) -> bool:
        """Connected within ``timeout_s`` (across a restart of the cyclic thread)."""
        deadline = time.monotonic() + timeout_s
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            try:
                return await self.cyclic.call(
                    functools.partial(self._wait_connected_on_loop, remaining)
                )
            except NotConnectedError:
                await asyncio.sleep(min(0.1, max(0.0, remaining)))


def _with_state(stats: ConnectionStats, state: ConnectionState, reason: str) -> ConnectionStats:
    return replace(stats, state=state, reason=reason)
