"""Layer: service. The event log: every event on the event bus into the database.

An event consumer (``events.bus``): ``Store.log_event`` queues the row for the store's writer
thread, so the bus never waits on the disk (on a full disk the events wait in memory until it
has room, ``storage.queued_writer``; those given up are counted:
``cobot_hmi_event_write_errors_total``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

from cobot_hmi.service.events.text import Event
from cobot_hmi.service.storage.store import Store


class EventLog:
    """Events into the store's ``events`` table (see the module docstring)."""

    name: Final = "event-log"

    def __init__(self, store: Store) -> None:
        self._store = store

    def on_events(self, events: Sequence[Event]) -> None:
        for event in events:
            self._store.log_event(event)
