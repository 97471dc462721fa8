"""Layer: service. What of the audit trail could not be written yet, kept in memory until the
disk has room again (``service.storage.store``); imports nothing of the project.

A write the robot confirmed, control taken or released, a session's control dropped: these
happened, and their audit rows (or a ``pending`` row's outcome) must reach the database even
when the disk is full at that moment. The store keeps them here and writes them, in the order
they came, before anything else it writes and every ``store.AUDIT_RETRY_S`` until they are in.
Nothing new is acted on meanwhile: an action whose own row must be written before it acts (a
write's ``pending`` row) is refused while this cannot be written, so what waits here is at
most what was in flight when the disk filled, plus the drops. Refusals (nothing happened) are
kept too while there is room (``limit``); beyond it they are counted as lost and logged.

Used only from the store's worker thread.
"""

from __future__ import annotations

import logging
import sqlite3
from collections.abc import Callable
from dataclasses import dataclass

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class Deferred:
    """One audit write that has to wait."""

    write: Callable[[sqlite3.Connection], object]
    """Does it, inside the store's transaction."""
    what: str
    """It in words, for the log when it cannot be written at all (``control.take by ada``)."""
    happened: bool
    """The action took effect: kept whatever the limit."""


class AuditBacklog:
    """Audit writes waiting for room, oldest first."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.items: list[Deferred] = []
        self.lost = 0
        """Refusals' rows dropped because ``limit`` was reached."""
        self.kept_total = 0
        self.cause: str | None = None
        """Why the first one had to wait (``disk full (database or disk is full)``)."""

    def __len__(self) -> int:
        return len(self.items)

    def keep(self, item: Deferred, cause: str) -> bool:
        """Keep ``item`` until ``write`` succeeds; ``False``: dropped (a refusal over the
        limit: counted and logged)."""
        if not item.happened and len(self.items) >= self.limit:
            self.lost += 1
            log.error("audit row lost (%s, %d waiting): %s", cause, len(self.items), item.what)
            return False
        if not self.items:
            self.cause = cause
            log.error(
                "the audit trail cannot be written (%s): its rows wait in memory until it can",
                cause,
            )
        self.items.append(item)
        self.kept_total += 1
        return True

    def write(self, db: sqlite3.Connection) -> None:
        """Every waiting write, in order, in the caller's transaction (``done`` after its
        commit)."""
        for item in self.items:
            item.write(db)

    def done(self) -> None:
        """The caller's transaction with ``write`` committed."""
        if self.items:
            log.warning("the audit trail is written again (%d rows were waiting)", len(self.items))
        self.items.clear()
        self.cause = None

    def give_up(self) -> None:
        """The service stops and the disk is still full: what waits goes to the log (the
        rows stay ``pending``; the next start marks them ``interrupted``)."""
        for item in self.items:
            log.error("audit row not written (%s): %s", self.cause, item.what)
        self.items.clear()
