"""Layer: service (Sparkplug). The edge node's session numbers (Sparkplug 3.0, "Sparkplug
Session Management"): ``bdSeq`` and ``seq``.

``bdSeq`` (0–255) goes up by one with every MQTT CONNECT sent; the NDEATH registered as that
connection's will and the NBIRTH sent on it carry the same value, so a host application can
tell a stale death from the current session's. It is kept in a file of the state directory so
that a restarted service goes on counting (a late will of the previous process must not end the
new session). ``seq`` (0–255, wrapping) numbers every message after NBIRTH (which is 0),
NDEATH excepted.

Imports nothing of the project.
"""

from __future__ import annotations

import contextlib
import logging
import os
from pathlib import Path
from typing import Final

log = logging.getLogger(__name__)

SEQ_MODULO: Final = 256


class NodeSession:
    """``bdSeq`` (persisted) and ``seq`` of one edge node."""

    def __init__(self, state_file: Path | None) -> None:
        self._state_file = state_file
        self.bd_seq = self._load()
        """The bdSeq of the current (or next) MQTT connection."""
        self._seq = 0

    def _load(self) -> int:
        """The value after the one last used (0 on a first start or an unreadable file)."""
        if self._state_file is None:
            return 0
        try:
            return (int(self._state_file.read_text().strip()) + 1) % SEQ_MODULO
        except (OSError, ValueError):
            return 0

    def next_connection(self, advance: bool) -> int:
        """Before each connection attempt: the bdSeq its CONNECT carries; ``advance`` when the
        previous attempt sent a CONNECT (one that failed before reaching the broker did not)."""
        if advance:
            self.bd_seq = (self.bd_seq + 1) % SEQ_MODULO
        if self._state_file is not None:
            with contextlib.suppress(OSError):  # counting on in memory is the next best
                self._state_file.parent.mkdir(parents=True, exist_ok=True)
                temporary = self._state_file.with_suffix(".tmp")
                temporary.write_text(f"{self.bd_seq}\n")
                os.replace(temporary, self._state_file)
        return self.bd_seq

    def birth_seq(self) -> int:
        """NBIRTH's seq: 0, and the messages after it count on from there."""
        self._seq = 1
        return 0

    def next_seq(self) -> int:
        seq = self._seq
        self._seq = (seq + 1) % SEQ_MODULO
        return seq
