"""Layer: service. The WebSocket fan-out: one robot's frames and events to every client.

The fan-out is one of the robot's frame consumers (``robots.frame_notifier``), on the web loop,
and one of the event bus's consumers (``events.bus``). Nothing a client does can reach the cyclic
connection:

- The notifier hands the hub the frames since its last turn (about ``batch_s`` of them: the
  cell's robots share one wake of the loop, ``frames.LoopWake``);
  ``on_frames`` serializes each frame ONCE per set of fields asked for, then builds one
  message per group (clients asking the same rate and the same fields, by ``?rate=`` or a
  ``subscribe`` message: ``Subscription``) from those pieces and hands the same text to each
  client of the group. A client's ``offer`` is a deque append: O(1) per client per tick; a
  subscription moves its client to another group, it never makes the hub encode per client.
  A client whose sender is idle is written its frames at once where the server can
  (``offer_frames``, ``service.api.ws_deflate``): the same framed bytes for every client of
  the group, no task wake per client and message.
- ``on_events``: the robot's events (and the cell's), each serialized once, to every client;
  the events a frame caused arrive after it (``robots.watch`` is registered after the hub).
- A client of every field (a panel) is sent its frames uncompressed where the server can
  (``send_plain``: permessage-deflate is each connection's own, a deflate per client per frame
  at the robot's rate, ``service.api.ws_deflate``); a subscription to some fields (a phone's)
  and every other message go as the connection negotiated.
- Each client has its own bounded queue (in frames) and its own sender task. A slow client's
  queue overflows: its oldest frame messages are dropped, counted, and it is told with a
  ``dropped`` message before its next frames. A stalled client (one send stuck for
  ``stall_timeout_s``: the peer stopped reading and the TCP buffers are full) is disconnected.
  Events and the hello are never dropped.
"""

from __future__ import annotations

import asyncio
import contextlib
import enum
import logging
import time
from collections import deque
from collections.abc import Awaitable, Callable, Coroutine, Sequence
from dataclasses import dataclass, field
from typing import Any, Final

from cobot_hmi.codec import Frame, dumps, frame_to_json
from cobot_hmi.service.events.text import Event
from cobot_hmi.service.robots.frame_notifier import FrameRecord, Runs

log = logging.getLogger(__name__)

SendText = Callable[[str], Awaitable[None]]
WriteNow = Callable[[bytes], bool]
"""Writes a UTF-8 text message uncompressed at once if the connection takes it (True), else
writes nothing (False)."""
Abort = Callable[[str], Coroutine[Any, Any, None]]

QUEUE_FRAMES: Final = 4096
"""Frames the loop may fall behind by before the oldest are lost (~40 s at 10 ms)."""


Fields = tuple[str, ...] | None
"""The frame fields a client asked for, in the layout's order (None: every field)."""


@dataclass(frozen=True, slots=True)
class Subscription:
    """What a client is sent: the frame fields it shows, at the rate it draws (None: all)."""

    fields: Fields = None
    rate_hz: float | None = None


class Kind(enum.Enum):
    FRAMES = 1
    EVENT = 2
    STATUS = 3


@dataclass(slots=True, eq=False)  # identity semantics: clients live in sets
class StreamClient:
    """One WebSocket client: its queue, its sender and its counters."""

    send_text: SendText
    abort: Abort
    subscription: Subscription
    max_frames: int
    session_id: str | None = None
    client: str = ""
    send_plain: SendText | None = None
    """Sends a text message uncompressed (the server's, where it has one): frames of every
    field go by it."""
    write_now: WriteNow | None = None
    """The server's immediate uncompressed write, where it has one (``offer_frames``)."""
    queue: deque[tuple[Kind, str, int]] = field(default_factory=deque)
    queued_frames: int = 0
    dropped_pending: int = 0
    dropped_total: int = 0
    frames_sent: int = 0
    messages_sent: int = 0
    written_at_once: int = 0
    """Of ``messages_sent``, those written at once (``offer_frames``), not by the sender."""
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

    def offer_frames(self, text: str, message: bytes, frames: int) -> None:
        """Send a frames message (``text``, ``message`` its UTF-8): written at once when the
        client takes every field uncompressed, its sender is idle and the connection takes it
        (no task wake, nothing queued: most messages of a client that keeps up), else queued
        for its sender, behind what waits."""
        write_now = self.write_now
        if (
            write_now is not None
            and not self.queue
            and self.sending_since is None
            and self.closed_reason is None
            and self.subscription.fields is None
            and write_now(message)
        ):
            self.frames_sent += frames
            self.messages_sent += 1
            self.written_at_once += 1
            return
        self.offer(Kind.FRAMES, text, frames)

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
            plain = kind is Kind.FRAMES and self.subscription.fields is None
            await self._send(text, self.send_plain if plain else None)
            self.frames_sent += frames

    async def _send(self, text: str, send: SendText | None = None) -> None:
        self.sending_since = time.monotonic()
        await (send or self.send_text)(text)
        self.sending_since = None
        self.messages_sent += 1


class _RateGroup:
    """Clients that asked for the same rate and fields share one decimation and one message
    per tick."""

    def __init__(self, subscription: Subscription) -> None:
        self.fields = subscription.fields
        rate_hz = subscription.rate_hz
        self.period_s = 1.0 / rate_hz if rate_hz else 0.0
        self.next_due: float | None = None
        self.clients: list[StreamClient] = []

    def select(self, records: Sequence[FrameRecord]) -> list[int]:
        """Indexes of the frames this group sends: all, or decimated to ``rate_hz``.

        A frame is due from a quarter period early, so a rate equal to the frame rate keeps
        every frame despite receive jitter; dues advance by whole periods, so the mean rate is
        the asked one; after a pause in the stream the schedule restarts instead of bursting.
        """
        if not self.period_s:
            return list(range(len(records)))
        chosen = []
        for i, record in enumerate(records):
            t = record.received_at_s
            due = self.next_due
            if due is None or t >= due - 0.25 * self.period_s:
                chosen.append(i)
                due = t if due is None else due
                due += self.period_s
                if due <= t:
                    due = t + self.period_s
                self.next_due = due
        return chosen


class WebSocketFanOut:
    """Fan-out of one robot's frames and events to WebSocket clients (see the module
    docstring)."""

    name: Final = "websocket"
    runs: Final = Runs.LOOP
    queue_frames: Final = QUEUE_FRAMES

    def __init__(
        self,
        *,
        robot: str,
        batch_s: float,
        client_queue_frames: int,
        stall_timeout_s: float,
    ) -> None:
        """``robot``: the robot whose events this hub sends (the cell's too)."""
        self.robot = robot
        self.batch_s = batch_s
        self.client_queue_frames = client_queue_frames
        self.stall_timeout_s = stall_timeout_s
        self._groups: dict[Subscription, _RateGroup] = {}
        self.clients: set[StreamClient] = set()
        # Counters for /metrics.
        self.stalled_disconnects = 0
        self.dropped_frames_closed_clients = 0
        self.frames_sent_closed_clients = 0
        self.tick_seconds = 0.0
        self._background: set[asyncio.Task[None]] = set()
        self._last_frame: Frame | None = None
        self._last_frame_dict: dict[str, object] = {}
        self._frame_json_by_fields: dict[Fields, tuple[Frame, bytes]] = {}

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
        send_plain: SendText | None = None,
        write_now: WriteNow | None = None,
    ) -> StreamClient:
        """Register a client (every field at ``rate_hz``, until it subscribes), queue its hello
        first and start its sender. ``send_plain``, ``write_now``: the server's uncompressed
        send and immediate write, if any."""
        stream_client = StreamClient(
            send_text,
            abort,
            Subscription(None, rate_hz),
            self.client_queue_frames,
            session_id=session_id,
            client=client,
            send_plain=send_plain,
            write_now=write_now,
        )
        stream_client.offer(Kind.EVENT, dumps(hello).decode())
        self._join(stream_client)
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
        self._leave(stream_client)
        task = stream_client.task
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task

    def subscribe(self, stream_client: StreamClient, subscription: Subscription) -> None:
        """Send ``stream_client`` what ``subscription`` asks from the next tick on: it moves
        to that group (made if no other client asked the same), after a ``subscribed`` message
        saying so, so the frames it is sent after that message are the new ones."""
        if stream_client not in self.clients:
            return
        self._leave(stream_client)
        stream_client.subscription = subscription
        self._join(stream_client)
        fields = None if subscription.fields is None else list(subscription.fields)
        ack = {"type": "subscribed", "fields": fields, "rate_hz": subscription.rate_hz}
        stream_client.offer(Kind.EVENT, dumps(ack).decode())

    def _join(self, stream_client: StreamClient) -> None:
        group = self._groups.get(stream_client.subscription)
        if group is None:
            group = self._groups[stream_client.subscription] = _RateGroup(
                stream_client.subscription
            )
        group.clients.append(stream_client)

    def _leave(self, stream_client: StreamClient) -> None:
        group = self._groups.get(stream_client.subscription)
        if group is None:
            return
        group.clients.remove(stream_client)
        if not group.clients:
            del self._groups[stream_client.subscription]
            if all(g.fields != group.fields for g in self._groups.values()):
                self._frame_json_by_fields.pop(group.fields, None)

    async def close(self) -> None:
        """Stop every client's sender and finish pending disconnects."""
        for stream_client in list(self.clients):
            await self.remove_client(stream_client)
        if self._background:
            await asyncio.gather(*self._background, return_exceptions=True)

    @property
    def dropped_frames_total(self) -> int:
        return self.dropped_frames_closed_clients + sum(c.dropped_total for c in self.clients)

    @property
    def frames_sent_total(self) -> int:
        return self.frames_sent_closed_clients + sum(c.frames_sent for c in self.clients)

    # ------------------------------------------------------------ broadcasting

    def on_events(self, events: Sequence[Event]) -> None:
        """The event bus: this robot's events and the cell's to every client (never
        dropped)."""
        for event in events:
            robot = event.get("robot")
            if robot is not None and robot != self.robot:
                continue
            text = dumps({"type": "event", "event": event}).decode()
            for stream_client in self.clients:
                stream_client.offer(Kind.EVENT, text)

    def broadcast_status(self, status: dict[str, object]) -> None:
        text = dumps({"type": "status", **status}).decode()
        for stream_client in self.clients:
            stream_client.offer(Kind.STATUS, text)

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        """One broadcast: serialize each frame once per set of fields, one message per group,
        stalls."""
        started = time.perf_counter()
        if self._groups:
            pieces_by_fields: dict[Fields, list[bytes | None]] = {}
            for group in self._groups.values():
                chosen = group.select(records)
                if not chosen:
                    continue
                pieces = pieces_by_fields.get(group.fields)
                if pieces is None:
                    pieces = pieces_by_fields[group.fields] = [None] * len(records)
                for i in chosen:
                    if pieces[i] is None:
                        seq, t, frame, wire, _ = records[i]
                        pieces[i] = b"".join(
                            (
                                b'{"seq":',
                                str(seq).encode(),
                                b',"t":',
                                dumps(t),
                                b',"t2o_sequence":',
                                str(wire).encode(),
                                b',"frame":',
                                self._frame_json(frame, group.fields),
                                b"}",
                            )
                        )
                body = b",".join(pieces[i] or b"" for i in chosen)
                message = b'{"type":"frames","frames":[' + body + b"]}"
                text = message.decode()
                for stream_client in group.clients:
                    stream_client.offer_frames(text, message, len(chosen))
        self._check_stalls()
        self.tick_seconds += time.perf_counter() - started

    def _frame_json(self, frame: Frame, fields: Fields) -> bytes:
        """The frame's JSON (only ``fields`` of it), once per frame object and set of fields:
        the originator hands on the same immutable ``Frame`` while the robot's bytes do not
        change (a robot refreshes its monitoring values about every 100 ms, whatever the RPI),
        so most frames at short RPIs cost no encoding. Each set of fields keeps its own last
        frame, so groups asking different fields do not undo each other's."""
        cached = self._frame_json_by_fields.get(fields)
        if cached is not None and cached[0] is frame:
            return cached[1]
        if frame is not self._last_frame:
            self._last_frame = frame
            self._last_frame_dict = frame_to_json(frame)
        data = self._last_frame_dict
        if fields is not None:
            # A field's words go with it (robot_state_name with robot_state).
            data = {
                key: data[key] for name in fields for key in (name, f"{name}_name") if key in data
            }
        text = dumps(data)
        self._frame_json_by_fields[fields] = (frame, text)
        return text

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
        """Stall checks while no frames come (they also run after every broadcast): four per
        stall timeout, so a stall is caught within a quarter of the timeout past it. (Every two
        broadcast periods, 16 robots' hubs woke the web loop 160 times a second for them.)"""
        while True:
            await asyncio.sleep(self.stall_timeout_s / 4)
            try:
                self._check_stalls()
            except Exception:  # a bug here must not end the stream for everyone
                log.exception("WebSocket stall check failed")
