"""Layer: service. The one event bus: every event of every robot, to every consumer of events.

Events (``docs/api.md`` "Events": robot states, flags, connection, writes, control, alarms,
sessions, recording) are published here, once, by whoever sees them happen; the consumers
(the event log in the database, each robot's WebSocket fan-out, the Sparkplug B edge node, the
OPC UA server) implement ``EventConsumer`` and are registered the same way, as frame consumers
are with ``robots.frame_notifier.FrameNotifier``.

``publish`` runs on the web event loop and hands the event to each consumer in registration
order, at once: events are few (a handful a second at most) and never dropped. Each gets its
``text`` in words here, once (``events.text.with_text``). A thread that
sees an event (the recorder's) uses ``publish_threadsafe``. An event of one robot carries its
name (``robot``); the publisher sets it.

Must not import the web layer, the scanner or any consumer.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Sequence
from typing import Protocol

from cobot_hmi.service.events.text import Event, with_text

log = logging.getLogger(__name__)


class EventConsumer(Protocol):
    @property
    def name(self) -> str: ...

    def on_events(self, events: Sequence[Event]) -> None:
        """On the web loop; quick (queue, never wait)."""
        ...


class EventBus:
    """Events to their consumers (see the module docstring)."""

    def __init__(self) -> None:
        self.consumers: tuple[EventConsumer, ...] = ()
        self.published = 0
        self._loop: asyncio.AbstractEventLoop | None = None

    def add(self, consumer: EventConsumer) -> None:
        self.consumers = (*self.consumers, consumer)

    def remove(self, consumer: EventConsumer) -> None:
        self.consumers = tuple(c for c in self.consumers if c is not consumer)

    def bind_loop(self, loop: asyncio.AbstractEventLoop) -> None:
        """The web event loop, for ``publish_threadsafe``."""
        self._loop = loop

    def publish(self, robot: str | None, *events: Event) -> None:
        """On the web loop: ``events`` of ``robot`` (``None``: the cell's own) to everyone."""
        if not events:
            return
        for event in events:
            if robot is not None:
                event.setdefault("robot", robot)
            with_text(event)  # in words, once: the stream, the log and exports carry it
        self.published += len(events)
        for consumer in self.consumers:
            try:
                consumer.on_events(events)
            except Exception:  # one consumer's bug must not keep an event from the others
                log.exception("event consumer %s failed", consumer.name)

    def publish_threadsafe(self, robot: str | None, *events: Event) -> None:
        """From another thread: ``publish`` on the web loop (dropped only once it closed)."""
        loop = self._loop
        if loop is None:
            log.warning("event bus: no loop yet, %d event(s) not published", len(events))
            return
        with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
            loop.call_soon_threadsafe(lambda: self.publish(robot, *events))
