"""Layer: service. The class 1 connection to the robot, on its own thread and event loop.

The originator (``cobot_hmi.scanner.originator``) runs on a private asyncio loop in a thread
of its own, so web work (serializing frames, WebSocket sends, HTTP parsing, SQLite) never
delays a T→O receive or an O→T send by more than a GIL hand-over: the cyclic timing does not
depend on how many clients watch. Everything the web side asks of the originator goes through
``run_coroutine_threadsafe``; plain attribute reads (``state``, ``run``, ``command``) are
single loads under the GIL. The frame callback goes straight to ``Hub.on_frame`` on the
originator's thread (it is O(1) and thread-safe); state changes are handed to the web loop.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import logging
import os
import threading
from collections.abc import Awaitable, Callable
from typing import TypeVar

from cobot_hmi.codec import CommandImage, Frame
from cobot_hmi.eventloop import precise_event_loop
from cobot_hmi.scanner.originator import (
    ConnectionState,
    ConnectionStats,
    Originator,
    OriginatorSettings,
)

log = logging.getLogger(__name__)

_T = TypeVar("_T")

_JOIN_TIMEOUT_S = 10.0
"""How long stopping waits for the cyclic thread (Forward Close takes at most ~2 s)."""

FrameCallback = Callable[[Frame, float, int], None]
StateCallback = Callable[[ConnectionState, str | None], None]


class RobotLink:
    """Owns the originator and its thread. ``start`` once, ``stop`` once (Forward Close)."""

    def __init__(
        self,
        settings: OriginatorSettings,
        *,
        on_frame: FrameCallback,
        on_state: StateCallback,
        niceness: int = 0,
    ) -> None:
        self.settings = settings
        self.niceness = niceness
        self._on_frame = on_frame
        self._on_state = on_state
        self._web_loop: asyncio.AbstractEventLoop | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._originator: Originator | None = None
        self._stopping: asyncio.Event | None = None
        self._started: concurrent.futures.Future[None] = concurrent.futures.Future()

    # ------------------------------------------------------------ lifecycle

    async def start(self) -> None:
        """Start the thread and the originator (which then connects and reconnects itself)."""
        self._web_loop = asyncio.get_running_loop()
        self._thread = threading.Thread(target=self._thread_main, name="cyclic-io", daemon=True)
        self._thread.start()
        await asyncio.wrap_future(self._started)

    def _thread_main(self) -> None:
        if self.niceness:
            # Linux schedules threads one by one: this raises (or lowers) only the cyclic
            # thread, so a busy host delays its wake-ups less. Not permitted: keep going as is.
            try:
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), self.niceness)
            except OSError as error:
                log.warning("cyclic thread priority unchanged (nice %d): %s", self.niceness, error)
        # Sub-millisecond timers for the O→T schedule (see ``cobot_hmi.eventloop``).
        loop = precise_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._main())
        finally:
            with contextlib.suppress(Exception):
                loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _main(self) -> None:
        self._stopping = asyncio.Event()
        originator = Originator(
            self.settings, on_frame=self._on_frame, on_state=self._state_from_thread
        )
        self._originator = originator
        try:
            await originator.start()
        except BaseException as error:
            self._started.set_exception(error)
            return
        self._started.set_result(None)
        await self._stopping.wait()
        try:
            await originator.stop()  # Forward Close and UnRegisterSession
        except Exception:
            log.exception("stopping the originator failed")

    def _state_from_thread(self, state: ConnectionState, reason: str | None) -> None:
        loop = self._web_loop
        if loop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(self._on_state, state, reason)

    async def stop(self) -> None:
        """Close the connection (Forward Close) and end the thread. Idempotent."""
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

    # ------------------------------------------------------------ reads

    @property
    def originator(self) -> Originator:
        assert self._originator is not None, "RobotLink.start() first"
        return self._originator

    @property
    def state(self) -> ConnectionState:
        return self.originator.state

    @property
    def reason(self) -> str | None:
        return self.originator.reason

    @property
    def run(self) -> bool:
        return self.originator.run

    @property
    def command(self) -> CommandImage:
        return self.originator.command

    @property
    def latest(self) -> tuple[Frame, float] | None:
        return self.originator.latest

    # ------------------------------------------------------------ calls on the cyclic loop

    async def _call(self, make: Callable[[], Awaitable[_T]]) -> _T:
        loop = self._loop
        assert loop is not None, "RobotLink.start() first"

        async def call() -> _T:
            return await make()

        return await asyncio.wrap_future(asyncio.run_coroutine_threadsafe(call(), loop))

    async def _call_sync(self, function: Callable[[], _T]) -> _T:
        async def call() -> _T:
            return function()

        return await self._call(call)

    async def stats(self) -> ConnectionStats:
        return await self._call_sync(self.originator.stats)

    async def set_run(self, run: bool) -> None:
        """Run or idle; raises the originator's ``ReadOnlyError`` / ``NotConnectedError``."""
        await self._call_sync(lambda: self.originator.set_run(run))

    async def set_command(self, image: CommandImage) -> int:
        """Replace the O→T image; the packets_out count after which it is on the wire."""
        return await self._call_sync(lambda: self.originator.set_command(image))

    async def wait_sent(self, packets_out: int, timeout_s: float) -> bool:
        return await self._call(lambda: self.originator.wait_sent(packets_out, timeout_s))

    async def wait_connected(self, timeout_s: float) -> bool:
        return await self._call(lambda: self.originator.wait_connected(timeout_s))
