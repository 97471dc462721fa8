"""Layer: service. One robot's frames, published once, handed to every consumer the same way.

The shape is python-can's ``Notifier`` and ``Listener``: the originator's callback publishes each
frame ONCE into the robot's ``FrameNotifier`` as a ``FrameRecord`` (the decoded frame, the raw
T→O payload it came from, the kernel's receive time and the wire sequence number); every
consumer (the WebSocket fan-out, the state and alarm events, write confirmation, the recorder,
the Sparkplug B edge node, the OPC UA server) implements ``FrameConsumer`` and is registered the
same way, by ``FrameNotifier.add``. A consumer declares where it runs:

- ``Runs.LOOP``: on the web event loop. Every notifier bound to one loop (the cell's robots)
  shares one ``LoopWake``, whose turn serves every robot's consumers at once, each consumer
  the frames queued for it since its last turn, in registration order. A notifier given a
  ``turn_period_s`` (the broadcast period) is served by the loop's own timer, a turn every
  period on a fixed grid: one wake of the loop per period for the whole cell, none from the
  cyclic thread. (Asking for a turn when a robot had ``frames_per_wake`` frames, the first
  robot of a cell to get there set the pace: with 32 robots at phases spread over the period
  the turns came every 4 frames of 5, a quarter more turns and WebSocket messages than the
  period asked for.) Without a period the notifier asks for a turn once it has
  ``frames_per_wake`` frames since the last one (one ``call_soon_threadsafe``; with a period,
  at twice that, should the timer fall behind). On every frame while a consumer asks to be
  ``urgent`` (a write waiting for its confirmation) the loop is woken for it at once.
- ``Runs.THREAD``: on a thread of the consumer's own (the recorder's), which takes its frames
  on its own schedule with ``Registration.deliver`` (``on_frames`` then runs on that thread).

On the cyclic thread a frame costs one record and one ``deque.append`` per consumer: O(1) per
consumer, never a wait (no lock either: the originator's frame callback on the cyclic thread is
the one producer of a robot's frames, and a restarted cyclic thread starts only after the old
one has ended). Each registration's queue is bounded (``queue_frames``): when a
consumer falls behind its oldest frames go and are counted (``dropped``, in ``/metrics`` as
``cobot_hmi_consumer_dropped_frames_total{robot,consumer}``), so no consumer can stall the
cyclic connection or grow without bound.

Must not import the web layer (FastAPI), the scanner or any consumer.
"""

from __future__ import annotations

import asyncio
import contextlib
import enum
import logging
import threading
import weakref
from collections import deque
from collections.abc import Sequence
from typing import NamedTuple, Protocol

from cobot_hmi.codec import Frame

log = logging.getLogger(__name__)


class FrameRecord(NamedTuple):
    """One T→O frame of one robot, as every consumer receives it (a tuple: cheap to make on
    the cyclic thread, and its first four fields read as ``seq, received_at_s, frame,
    t2o_sequence``)."""

    seq: int
    """The notifier's own counter: rises by one per frame published (a step of more than one
    in what a consumer saw means its queue dropped frames)."""
    received_at_s: float
    """Epoch seconds the kernel received the T→O packet."""
    frame: Frame
    """Decoded once, by the originator."""
    t2o_sequence: int
    """The encapsulation sequence number the packet carried on the wire (CIP Vol 2 §3-4.1): a
    step of more than one shows packets the scanner never received."""
    raw: bytes
    """The T→O payload the frame was decoded from (the layout's 284 bytes): consumers that
    store bytes slice these instead of encoding the frame again."""


class Runs(enum.Enum):
    """Where a consumer's ``on_frames`` runs."""

    LOOP = "loop"
    """On the web event loop, woken every ``frames_per_wake`` frames (or every frame while
    urgent)."""
    THREAD = "thread"
    """On a thread of the consumer's own, which calls ``Registration.deliver``."""


class FrameConsumer(Protocol):
    """What the notifier needs of a consumer (python-can's ``Listener``)."""

    @property
    def name(self) -> str:
        """Short and stable: the ``consumer`` label of its metrics ("websocket", "history")."""
        ...

    @property
    def runs(self) -> Runs: ...

    @property
    def queue_frames(self) -> int:
        """Frames its queue holds before the oldest are dropped."""
        ...

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        """``robot``'s frames queued since the last call, oldest first."""
        ...


_new_record = tuple.__new__
"""``FrameRecord(...)`` without the NamedTuple's own ``__new__`` (a Python function: a frame
of its own per record on the cyclic thread), as the generated decoder makes its frames."""


class Registration:
    """One consumer on one robot: its bounded queue and its counters."""

    __slots__ = (
        "_urgent",
        "_urgent_ones",
        "consumer",
        "delivered",
        "dropped",
        "queue",
        "queue_frames",
        "robot",
    )

    def __init__(
        self,
        robot: str,
        consumer: FrameConsumer,
        urgent_ones: set[Registration] | None = None,
    ) -> None:
        """``urgent_ones``: the notifier's set of its urgent registrations (this one joins it
        while it is urgent), so the cyclic thread asks one set, not every registration."""
        self.robot = robot
        self.consumer = consumer
        self.queue_frames = max(1, consumer.queue_frames)
        self.queue: deque[FrameRecord] = deque(maxlen=self.queue_frames)
        self.dropped = 0
        """Frames that fell out of the full queue (a drain racing the append may make this one
        too high, never too low)."""
        self.delivered = 0
        self._urgent = False
        self._urgent_ones = set() if urgent_ones is None else urgent_ones

    @property
    def urgent(self) -> bool:
        """Set by a loop consumer that wants every frame at once (a write waiting)."""
        return self._urgent

    @urgent.setter
    def urgent(self, urgent: bool) -> None:
        self._urgent = urgent
        if urgent:
            self._urgent_ones.add(self)
        else:
            self._urgent_ones.discard(self)

    @property
    def name(self) -> str:
        return self.consumer.name

    def offer(self, record: FrameRecord) -> None:
        """On the cyclic thread: append, counting the frame that falls out
        (``FrameNotifier.publish`` does the same inline, without a call per consumer)."""
        queue = self.queue
        if len(queue) == self.queue_frames:
            self.dropped += 1
        queue.append(record)

    def drain(self) -> list[FrameRecord]:
        """Every queued frame, oldest first (from any thread but the producer's)."""
        queue = self.queue
        records = []
        while queue:
            try:
                records.append(queue.popleft())
            except IndexError:  # pragma: no cover - emptied between the check and the pop
                break
        return records

    def deliver(self) -> None:
        """Hand the queued frames to the consumer (on the thread or loop it runs on)."""
        if not self.queue:  # the common case at a turn of the web loop: no call
            return
        records = self.drain()
        self.delivered += len(records)
        try:
            self.consumer.on_frames(self.robot, records)
        except Exception:  # one consumer's bug must not starve the others
            log.exception("frame consumer %s failed", self.consumer.name)


class LoopWake:
    """One wake of a loop for every notifier bound to it (see the module docstring)."""

    def __init__(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = weakref.ref(loop)  # the loop's own entry in ``_WAKES`` must not hold it
        self._notifiers: weakref.WeakSet[FrameNotifier] = weakref.WeakSet()
        self._turn: tuple[weakref.ref[FrameNotifier], ...] = ()
        """The notifiers as weak references, in attach order: what a turn walks (a WeakSet's
        iteration is a Python generator with a guard of its own)."""
        self._scheduled = False
        self._period_s: float | None = None
        """The timer's period: the shortest of the attached notifiers' (None: no timer)."""
        self._next_turn_s = 0.0
        self._timer: asyncio.TimerHandle | None = None
        self.timed_turns = 0
        """Turns the timer made (for the tests)."""

    @classmethod
    def of(cls, loop: asyncio.AbstractEventLoop) -> LoopWake:
        """The one wake of ``loop`` (made by its first notifier)."""
        wake = _WAKES.get(loop)
        if wake is None:
            wake = _WAKES[loop] = cls(loop)
        return wake

    def attach(self, notifier: FrameNotifier) -> None:
        if notifier not in self._notifiers:
            self._notifiers.add(notifier)
            self._turn = (*(r for r in self._turn if r() is not None), weakref.ref(notifier))

    def request(self) -> None:
        """From the cyclic thread: wake the loop unless a wake is on its way."""
        if self._scheduled:
            return
        loop = self._loop()
        if loop is None:
            return
        self._scheduled = True
        with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
            loop.call_soon_threadsafe(self._run)

    def _run(self) -> None:
        self._scheduled = False  # before the turns: a frame published meanwhile asks again
        for reference in self._turn:
            notifier = reference()
            if notifier is not None:
                notifier.dispatch_now()

    def turn_every(self, period_s: float) -> None:
        """On the loop: a turn every ``period_s`` (or the shorter period it has), from now."""
        if self._period_s is not None and self._period_s <= period_s:
            return
        self._period_s = period_s
        loop = self._loop()
        if loop is None:
            return
        if self._timer is not None:
            self._timer.cancel()
        self._next_turn_s = loop.time() + period_s
        self._timer = loop.call_at(self._next_turn_s, self._timed_turn)

    def _timed_turn(self) -> None:
        """A turn on the timer's grid, then the next one: a period later, or, when this one
        came more than a period late, a period from now (no burst of turns to catch up)."""
        self._timer = None
        loop = self._loop()
        period_s = self._period_s
        if loop is None or period_s is None or not any(r() is not None for r in self._turn):
            self._period_s = None  # every notifier is gone: the timer ends with them
            return
        try:
            self.timed_turns += 1
            self._run()
        finally:
            now = loop.time()
            self._next_turn_s += period_s
            if self._next_turn_s <= now:
                self._next_turn_s = now + period_s
            self._timer = loop.call_at(self._next_turn_s, self._timed_turn)


_WAKES: weakref.WeakKeyDictionary[asyncio.AbstractEventLoop, LoopWake] = weakref.WeakKeyDictionary()


class FrameNotifier:
    """One robot's frames to its consumers (see the module docstring)."""

    def __init__(
        self, robot: str, *, frames_per_wake: int = 1, turn_period_s: float | None = None
    ) -> None:
        """``frames_per_wake``: the frames of a broadcast period; ``turn_period_s``: that
        period, for the loop's timer (None: a turn asked for every ``frames_per_wake``)."""
        self.robot = robot
        self.frames_per_wake = max(1, frames_per_wake)
        self.turn_period_s = turn_period_s if self.frames_per_wake > 1 else None
        """The loop's timer serves this robot (a robot with a frame per period or fewer asks
        for a turn at each frame instead)."""
        self._wake_after = self.frames_per_wake * (2 if self.turn_period_s else 1)
        """Frames since the last turn at which this robot asks for one itself."""
        self._seq = 0
        self._registering = threading.Lock()
        self.latest: FrameRecord | None = None
        """The newest frame (any thread may read it: one reference)."""
        self.registrations: tuple[Registration, ...] = ()
        """Every consumer of this robot, in registration order (a new tuple swapped in whole:
        the cyclic thread iterates whichever it read)."""
        self._loop_registrations: tuple[Registration, ...] = ()
        self._offers: tuple[tuple[deque[FrameRecord], int, Registration], ...] = ()
        """Each registration's queue, bound and itself, for ``publish``'s loop (swapped in whole
        with ``registrations``)."""
        self._urgent_ones: set[Registration] = set()
        """The loop registrations urgent now (set on the web loop, read on the cyclic thread:
        one truth test)."""
        self._loop: asyncio.AbstractEventLoop | None = None
        self._wake: LoopWake | None = None
        self._since_turn = 0
        """Frames published since the loop consumers' last turn (a race with the loop's reset
        can only make one wake early)."""
        self._urgent_scheduled = False

    # ------------------------------------------------------------ the cyclic thread

    def publish(self, frame: Frame, raw: bytes, received_at_s: float, t2o_sequence: int) -> None:
        """The originator's callback: one record, one append per consumer, a wake. From the
        one producer thread (see the module docstring): no lock."""
        seq = self._seq = self._seq + 1
        record: FrameRecord = _new_record(
            FrameRecord, (seq, received_at_s, frame, t2o_sequence, raw)
        )
        self.latest = record
        for queue, queue_frames, registration in self._offers:  # ``Registration.offer``, inline
            if len(queue) == queue_frames:
                registration.dropped += 1
            queue.append(record)
        wake = self._wake
        if wake is None or not self._loop_registrations:
            return
        since_turn = self._since_turn = self._since_turn + 1
        if since_turn >= self._wake_after:
            wake.request()
        elif self._urgent_ones and not self._urgent_scheduled:
            loop = self._loop
            assert loop is not None  # bound with the wake
            self._urgent_scheduled = True
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(self._dispatch_urgent)

    @property
    def seq(self) -> int:
        """The number of the newest frame published (0 before the first)."""
        return self._seq

    # ------------------------------------------------------------ registering

    def add(self, consumer: FrameConsumer) -> Registration:
        """Register ``consumer``: from now on it receives every frame of this robot."""
        registration = Registration(self.robot, consumer, self._urgent_ones)
        with self._registering:  # from any thread (the OPC UA server registers from its own)
            self.registrations = (*self.registrations, registration)
            self._offers = _offers_of(self.registrations)
            if consumer.runs is Runs.LOOP:
                self._loop_registrations = (*self._loop_registrations, registration)
        return registration

    def remove(self, registration: Registration) -> None:
        with self._registering:
            self.registrations = tuple(r for r in self.registrations if r is not registration)
            self._offers = _offers_of(self.registrations)
            self._loop_registrations = tuple(
                r for r in self._loop_registrations if r is not registration
            )
            registration.urgent = False

    def dropped_by(self, consumer_name: str) -> int:
        """Frames the queues of the consumers called ``consumer_name`` dropped."""
        return sum(r.dropped for r in self.registrations if r.name == consumer_name)

    def bind_loop(self, loop: asyncio.AbstractEventLoop) -> None:
        """The web event loop that runs the loop consumers (before the first frame; on that
        loop when the notifier has a ``turn_period_s``, whose timer it starts)."""
        self._loop = loop
        self._wake = LoopWake.of(loop)
        self._wake.attach(self)
        if self.turn_period_s is not None:
            self._wake.turn_every(self.turn_period_s)

    # ------------------------------------------------------------ the web loop

    def _dispatch(self) -> None:
        self._since_turn = 0
        for registration in self._loop_registrations:
            registration.deliver()

    def _dispatch_urgent(self) -> None:
        self._urgent_scheduled = False
        for registration in self._loop_registrations:
            if registration.urgent:
                registration.deliver()

    def dispatch_now(self) -> None:
        """On the web loop: every loop consumer's queued frames at once (a consumer that has
        just become urgent catches up without waiting for the next frame)."""
        self._dispatch()


def _offers_of(
    registrations: tuple[Registration, ...],
) -> tuple[tuple[deque[FrameRecord], int, Registration], ...]:
    return tuple((r.queue, r.queue_frames, r) for r in registrations)
