"""Layer: service. The WebSocket fan-out: frames from the cyclic connection to every client.

The work is split so that nothing a client does can reach the cyclic connection:

- ``Hub.on_frame`` is the originator's callback. It runs on the cyclic connection's own thread
  and does O(1) work: a counter, one ``deque.append``, on every ``frames_per_batch``-th frame a
  ``call_soon_threadsafe`` to wake the broadcast loop, and one more while a write waits for its
  confirmation. It never serializes, never touches a client.
- ``Hub.run`` (the broadcast loop, on the web event loop) wakes after every
  ``frames_per_batch`` frames (``batch_s`` of them), drains the new frames, serializes each
  frame ONCE, then builds one message per rate group (clients asking the same ``?rate=``) from
  those pieces and hands the same text to each client of the group. A client's ``offer`` is a
  deque append: O(1) per client per tick.
- The robot's alarm engine (``service.alarms``) sees every frame the loop drains, in order,
  before the frames are sent (``Hub.alarms.observe``: nothing allocated unless an alarm
  changes); its events follow the frame's own.
- Each client has its own bounded queue (in frames) and its own sender task. A slow client's
  queue overflows: its oldest frame messages are dropped, counted, and it is told with a
  ``dropped`` message before its next frames. A stalled client (one send stuck for
  ``stall_timeout_s``: the peer stopped reading and the TCP buffers are full) is disconnected.
  Events and the hello are never dropped.

Consumers other than WebSocket clients (the Sparkplug B edge node) ``subscribe``: a bounded
queue of their own that ``on_frame`` appends every frame to (O(1); the oldest dropped and
counted when full) and that they drain on their own schedule.
"""

from __future__ import annotations

import asyncio
import bisect
import contextlib
import enum
import logging
import threading
import time
from collections import deque
from collections.abc import Awaitable, Callable, Coroutine
from dataclasses import dataclass, field
from typing import Any, Final, Protocol

from cobot_hmi.codec import Frame, dumps, frame_to_json
from cobot_hmi.service.events.text import Event, FrameWatcher, with_text

log = logging.getLogger(__name__)

FrameItem = tuple[int, float, Frame, int]
"""``(seq, received_at, frame, t2o_sequence)``: ``seq`` is the hub's own frame counter
(monotonic, rising by one per frame the hub took: a step shows a frame lost after the scanner),
``t2o_sequence`` the encapsulation sequence number the frame's T→O packet carried on the wire
(a step of more than one shows packets the scanner did not deliver)."""

SendText = Callable[[str], Awaitable[None]]
Abort = Callable[[str], Coroutine[Any, Any, None]]

_INBOX_FRAMES: Final = 4096
"""Frames the broadcast loop may fall behind by before the oldest are lost (~40 s at 10 ms)."""

_INTERVAL_BUCKETS_S: Final = (
    *(i / 4000 for i in range(120)),  # 0 … 29.75 ms in 0.25 ms steps: p99 near the RPI
    *(i / 1000 for i in (30, 40, 50, 75, 100, 250, 500, 1000)),
)
"""Upper bounds of the receive-interval histogram, seconds."""


class FrameAlarms(Protocol):
    """The robot's alarm engine (``service.alarms.engine.AlarmEngine``) as the hub sees it."""

    def observe(self, frame: Frame, time_s: float) -> list[Event] | None: ...


class Kind(enum.Enum):
    FRAMES = 1
    EVENT = 2
    STATUS = 3


@dataclass(slots=True, eq=False)  # identity semantics: clients live in sets
class StreamClient:
    """One WebSocket client: its queue, its sender and its counters."""

    send_text: SendText
    abort: Abort
    rate_hz: float | None
    max_frames: int
    session_id: str | None = None
    client: str = ""
    queue: deque[tuple[Kind, str, int]] = field(default_factory=deque)
    queued_frames: int = 0
    dropped_pending: int = 0
    dropped_total: int = 0
    frames_sent: int = 0
    messages_sent: int = 0
    sending_since: float | None = None
    """``time.monotonic()`` when the send in progress started; ``None`` when idle."""
    closed_reason: str | None = None
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    task: asyncio.Task[None] | None = None

    def offer(self, kind: Kind, text: str, frames: int = 0) -> None:
        """Queue a message. Over the frame bound the oldest frame messages go first."""
        if kind is Kind.STATUS:
            # An unsent status is superseded by the new one.
            for i, (k, _, _) in enumerate(self.queue):
                if k is Kind.STATUS:
                    del self.queue[i]
                    break
        self.queue.append((kind, text, frames))
        if frames:
            self.queued_frames += frames
            while self.queued_frames > self.max_frames and self._drop_oldest_frames():
                pass
        self.wake.set()

    def _drop_oldest_frames(self) -> bool:
        """Drop the oldest frames message that is not the newest one; False if there is none."""
        last = len(self.queue) - 1
        for i, (k, _, n) in enumerate(self.queue):
            if k is Kind.FRAMES and i != last:
                del self.queue[i]
                self.queued_frames -= n
                self.dropped_pending += n
                self.dropped_total += n
                return True
        return False

    async def run(self) -> None:
        """Send the queue until the connection ends; a failed send disconnects the client."""
        try:
            await self._send_queue()
        except asyncio.CancelledError:
            raise
        except Exception as error:  # the peer went away mid-send: end this client only
            if self.closed_reason is None:
                self.closed_reason = f"send failed: {type(error).__name__}"
                await self.abort(self.closed_reason)

    async def _send_queue(self) -> None:
        """Send the queue in order; a ``dropped`` notice precedes the frames after a loss."""
        while True:
            while not self.queue:
                self.wake.clear()
                await self.wake.wait()
            kind, text, frames = self.queue.popleft()
            if kind is Kind.FRAMES:
                self.queued_frames -= frames
                if self.dropped_pending:
                    count, self.dropped_pending = self.dropped_pending, 0
                    await self._send(dumps({"type": "dropped", "count": count}).decode())
            await self._send(text)
            self.frames_sent += frames

    async def _send(self, text: str) -> None:
        self.sending_since = time.monotonic()
        await self.send_text(text)
        self.sending_since = None
        self.messages_sent += 1


class _RateGroup:
    """Clients that asked for the same rate share one decimation and one message per tick."""

    def __init__(self, rate_hz: float | None) -> None:
        self.rate_hz = rate_hz
        self.period_s = 1.0 / rate_hz if rate_hz else 0.0
        self.next_due: float | None = None
        self.clients: list[StreamClient] = []

    def select(self, items: list[FrameItem]) -> list[int]:
        """Indexes of the frames this group sends: all, or decimated to ``rate_hz``.

        A frame is due from a quarter period early, so a rate equal to the frame rate keeps
        every frame despite receive jitter; dues advance by whole periods, so the mean rate is
        the asked one; after a pause in the stream the schedule restarts instead of bursting.
        """
        if not self.period_s:
            return list(range(len(items)))
        chosen = []
        for i, (_, t, _, _) in enumerate(items):
            due = self.next_due
            if due is None or t >= due - 0.25 * self.period_s:
                chosen.append(i)
                due = t if due is None else due
                due += self.period_s
                if due <= t:
                    due = t + self.period_s
                self.next_due = due
        return chosen


class FrameSubscription:
    """A consumer other than the WebSocket fan-out (the Sparkplug edge node, a recorder): every
    frame, in order, in a bounded queue of its own that the consumer drains at its own pace.

    The cyclic thread appends (O(1)); when the queue is full the oldest frame goes and is
    counted in ``dropped`` (a drain racing the append may make that count one too high, never
    too low). The consumer never makes the cyclic connection wait.
    """

    __slots__ = ("dropped", "max_frames", "name", "queue")

    def __init__(self, name: str, max_frames: int) -> None:
        self.name = name
        self.max_frames = max_frames
        self.queue: deque[FrameItem] = deque(maxlen=max_frames)
        self.dropped = 0

    def offer(self, item: FrameItem) -> None:
        """On the cyclic thread: append, counting the frame that falls out."""
        queue = self.queue
        if len(queue) == self.max_frames:
            self.dropped += 1
        queue.append(item)

    def drain(self) -> list[FrameItem]:
        """Every queued frame, oldest first (any thread other than the producer's)."""
        queue = self.queue
        items = []
        while queue:
            try:
                items.append(queue.popleft())
            except IndexError:  # pragma: no cover - emptied between the check and the pop
                break
        return items


class _FrameWaiter:
    __slots__ = ("after_seq", "future", "predicate")

    def __init__(
        self,
        after_seq: int,
        predicate: Callable[[Frame], bool],
        future: asyncio.Future[FrameItem],
    ) -> None:
        self.after_seq = after_seq
        self.predicate = predicate
        self.future = future


class Hub:
    """Fan-out of frames and events to WebSocket clients (see the module docstring)."""

    def __init__(
        self,
        *,
        batch_s: float,
        queue_frames: int,
        stall_timeout_s: float,
        frames_per_batch: int = 1,
        on_events: Callable[[list[Event]], None] | None = None,
        robot: str | None = None,
    ) -> None:
        """``robot``: the name every event of this hub carries (one hub per robot)."""
        self.robot = robot
        self.batch_s = batch_s
        self.frames_per_batch = max(1, frames_per_batch)
        self._batch_wake: asyncio.Event | None = None
        self.queue_frames = queue_frames
        self.stall_timeout_s = stall_timeout_s
        self._on_events = on_events
        self._inbox: deque[FrameItem] = deque(maxlen=_INBOX_FRAMES)
        self._seq = 0
        self._seq_lock = threading.Lock()
        self.latest: FrameItem | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._waiters: list[_FrameWaiter] = []
        self._wake_scheduled = False
        self._groups: dict[float | None, _RateGroup] = {}
        self.clients: set[StreamClient] = set()
        self._watcher = FrameWatcher()
        self.alarms: FrameAlarms | None = None
        """Evaluated on every frame in ``tick``, its events after the frame's own."""
        self._subscriptions: tuple[FrameSubscription, ...] = ()
        self._last_broadcast_seq = 0
        self._last_interval_t: float | None = None
        # Counters for /metrics.
        self.frames_in = 0
        self.frames_lost_in_hub = 0
        self.frames_broadcast = 0
        self.stalled_disconnects = 0
        self.dropped_frames_closed_clients = 0
        self.frames_sent_closed_clients = 0
        self.interval_buckets = [0] * (len(_INTERVAL_BUCKETS_S) + 1)
        self.interval_sum_s = 0.0
        self.interval_count = 0
        self.tick_seconds = 0.0
        self._background: set[asyncio.Task[None]] = set()

    # ------------------------------------------------------------ cyclic thread side

    def on_frame(self, frame: Frame, received_at: float, t2o_sequence: int) -> None:
        """The originator's callback (its own thread): O(1), see the module docstring;
        ``t2o_sequence`` rides in the item beside the hub's own counter."""
        with self._seq_lock:  # uncontended; guards against a second producer thread
            self._seq += 1
            item = (self._seq, received_at, frame, t2o_sequence)
        self._inbox.append(item)
        self.latest = item
        for subscription in self._subscriptions:
            subscription.offer(item)
        loop = self._loop
        if loop is not None and item[0] % self.frames_per_batch == 0:
            with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
                loop.call_soon_threadsafe(self._wake_batch)
        if self._waiters and not self._wake_scheduled and self._loop is not None:
            self._wake_scheduled = True
            with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
                self._loop.call_soon_threadsafe(self._check_waiters)

    @property
    def seq(self) -> int:
        return self._seq

    # ------------------------------------------------------------ other consumers

    def subscribe(self, name: str, max_frames: int) -> FrameSubscription:
        """A bounded queue that receives every frame from now on (``FrameSubscription``)."""
        subscription = FrameSubscription(name, max_frames)
        # A new tuple, swapped in whole: the cyclic thread iterates whichever it read.
        self._subscriptions = (*self._subscriptions, subscription)
        return subscription

    def unsubscribe(self, subscription: FrameSubscription) -> None:
        self._subscriptions = tuple(s for s in self._subscriptions if s is not subscription)

    # ------------------------------------------------------------ frame waiters (writes)

    def _check_waiters(self) -> None:
        self._wake_scheduled = False
        latest = self.latest
        if latest is None:
            return
        still = []
        for waiter in self._waiters:
            if waiter.future.done():
                continue
            if latest[0] > waiter.after_seq and waiter.predicate(latest[2]):
                waiter.future.set_result(latest)
            else:
                still.append(waiter)
        self._waiters = still

    async def wait_for_frame(
        self, predicate: Callable[[Frame], bool], after_seq: int, timeout_s: float
    ) -> FrameItem | None:
        """The first frame newer than ``after_seq`` for which ``predicate`` holds, or ``None``
        after ``timeout_s``. Checked on the newest frame each time frames arrive."""
        loop = asyncio.get_running_loop()
        self._loop = loop
        waiter = _FrameWaiter(after_seq, predicate, loop.create_future())
        self._waiters.append(waiter)
        self._check_waiters()
        try:
            async with asyncio.timeout(timeout_s):
                return await waiter.future
        except TimeoutError:
            return None
        finally:
            if waiter in self._waiters:
                self._waiters.remove(waiter)

    # ------------------------------------------------------------ clients

    def add_client(
        self,
        send_text: SendText,
        abort: Abort,
        rate_hz: float | None,
        hello: dict[str, object],
        *,
        session_id: str | None = None,
        client: str = "",
    ) -> StreamClient:
        """Register a client, queue its hello first and start its sender."""
        stream_client = StreamClient(
            send_text, abort, rate_hz, self.queue_frames, session_id=session_id, client=client
        )
        stream_client.offer(Kind.EVENT, dumps(hello).decode())
        group = self._groups.get(rate_hz)
        if group is None:
            group = self._groups[rate_hz] = _RateGroup(rate_hz)
        group.clients.append(stream_client)
        self.clients.add(stream_client)
        stream_client.task = asyncio.create_task(stream_client.run(), name=f"ws-send {client}")
        return stream_client

    async def remove_client(self, stream_client: StreamClient) -> None:
        """Stop the client's sender and forget it (idempotent)."""
        if stream_client not in self.clients:
            return
        self.clients.discard(stream_client)
        self.dropped_frames_closed_clients += stream_client.dropped_total
        self.frames_sent_closed_clients += stream_client.frames_sent
        group = self._groups.get(stream_client.rate_hz)
        if group is not None:
            group.clients.remove(stream_client)
            if not group.clients:
                del self._groups[stream_client.rate_hz]
        task = stream_client.task
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task

    async def close(self) -> None:
        """Stop every client's sender and finish pending disconnects."""
        for stream_client in list(self.clients):
            await self.remove_client(stream_client)
        if self._background:
            await asyncio.gather(*self._background, return_exceptions=True)
        for waiter in self._waiters:
            waiter.future.cancel()
        self._waiters.clear()

    @property
    def dropped_frames_total(self) -> int:
        return self.dropped_frames_closed_clients + sum(c.dropped_total for c in self.clients)

    @property
    def frames_sent_total(self) -> int:
        return self.frames_sent_closed_clients + sum(c.frames_sent for c in self.clients)

    # ------------------------------------------------------------ broadcasting

    def publish_event(self, event: Event) -> None:
        """Send an event to every client (never dropped) and hand it to ``on_events``."""
        self._broadcast_events([event])

    def _broadcast_events(self, events: list[Event]) -> None:
        for event in events:
            if self.robot is not None:
                event.setdefault("robot", self.robot)
            with_text(event)  # in words, once: the stream, the log and exports carry it
        if self._on_events is not None:
            self._on_events(events)
        for event in events:
            text = dumps({"type": "event", "event": event}).decode()
            for stream_client in self.clients:
                stream_client.offer(Kind.EVENT, text)

    def broadcast_status(self, status: dict[str, object]) -> None:
        text = dumps({"type": "status", **status}).decode()
        for stream_client in self.clients:
            stream_client.offer(Kind.STATUS, text)

    def tick(self) -> None:
        """One broadcast: drain, watch for events, serialize once, fan out, check stalls."""
        started = time.perf_counter()
        items: list[FrameItem] = []
        inbox = self._inbox
        while inbox:
            items.append(inbox.popleft())
        if items:
            self._account(items)
            events: list[Event] = []
            alarms = self.alarms
            for _, t, frame, _ in items:
                events.extend(self._watcher.observe(frame, t))
                if alarms is not None:
                    alarm_events = alarms.observe(frame, t)
                    if alarm_events:
                        events.extend(alarm_events)
            if self._groups:
                pieces: list[bytes | None] = [None] * len(items)
                for group in self._groups.values():
                    chosen = group.select(items)
                    if not chosen:
                        continue
                    for i in chosen:
                        if pieces[i] is None:
                            seq, t, frame, wire = items[i]
                            pieces[i] = dumps(
                                {
                                    "seq": seq,
                                    "t": t,
                                    "t2o_sequence": wire,
                                    "frame": frame_to_json(frame),
                                }
                            )
                    body = b",".join(pieces[i] or b"" for i in chosen)
                    text = (b'{"type":"frames","frames":[' + body + b"]}").decode()
                    for stream_client in group.clients:
                        stream_client.offer(Kind.FRAMES, text, len(chosen))
            if events:
                self._broadcast_events(events)
        self._check_stalls()
        self.tick_seconds += time.perf_counter() - started

    def _account(self, items: list[FrameItem]) -> None:
        first_seq = items[0][0]
        if self._last_broadcast_seq and first_seq > self._last_broadcast_seq + 1:
            self.frames_lost_in_hub += first_seq - self._last_broadcast_seq - 1
        self._last_broadcast_seq = items[-1][0]
        self.frames_in += len(items)
        self.frames_broadcast += len(items)
        previous = self._last_interval_t
        for _, t, _, _ in items:
            if previous is not None:
                interval = t - previous
                self.interval_sum_s += interval
                self.interval_count += 1
                self.interval_buckets[_bucket(interval)] += 1
            previous = t
        self._last_interval_t = previous

    def reset_interval_baseline(self) -> None:
        """Forget the last receive time (after a reconnect the first interval means nothing)."""
        self._last_interval_t = None

    def _check_stalls(self) -> None:
        now = time.monotonic()
        for stream_client in list(self.clients):
            since = stream_client.sending_since
            stalled = since is not None and now - since > self.stall_timeout_s
            if stalled and stream_client.closed_reason is None:
                stream_client.closed_reason = "stalled"
                self.stalled_disconnects += 1
                log.warning("WebSocket client %s stalled: disconnecting", stream_client.client)
                task = asyncio.create_task(stream_client.abort("stalled"))
                self._background.add(task)
                task.add_done_callback(self._background.discard)

    async def run(self) -> None:
        """The broadcast loop until cancelled: a ``tick`` every ``frames_per_batch`` frames,
        or every ``batch_s`` while no frames come (status, stall checks).

        Ticking right after a frame, not on a free-running timer, puts the burst of work a
        tick causes (serializing, every client's send, the clients' own reading on the same
        host) in the quiet time before the next frame: it never coincides with a receive.
        """
        loop = asyncio.get_running_loop()
        self._loop = loop
        self._batch_wake = asyncio.Event()
        while True:
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(self.batch_s * 2):
                    await self._batch_wake.wait()
            self._batch_wake.clear()
            try:
                self.tick()
            except Exception:  # a bug here must not end the stream for everyone
                log.exception("broadcast tick failed")

    def _wake_batch(self) -> None:
        if self._batch_wake is not None:
            self._batch_wake.set()

    def interval_histogram(self) -> list[tuple[float, int]]:
        """Cumulative (upper bound s, count) pairs, ``inf`` last, for Prometheus."""
        out = []
        running = 0
        for bound, count in zip(
            (*_INTERVAL_BUCKETS_S, float("inf")), self.interval_buckets, strict=True
        ):
            running += count
            out.append((bound, running))
        return out


def _bucket(interval_s: float) -> int:
    """Index of the first bucket whose upper bound is ≥ ``interval_s`` (last: +inf)."""
    return bisect.bisect_left(_INTERVAL_BUCKETS_S, interval_s)
