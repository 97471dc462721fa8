"""Layer: scanner. Imports nothing of the project.

Whether a target keeps the T→O packet interval it granted (issue 27). A Forward Open reply
grants an actual packet interval (API); some adapters then send on a timer of their own (OpENer
on loopback granted 2 ms and sent every 10 ms, its tick). The connection holds (the watchdog
spans 16 APIs and more), so without a word of it the only sign is every frame counted late.

The measure is the target's own: the time between two T→O packets received, divided by how
many packets it sent in between by its encapsulation sequence number (it rises by one per
packet sent, new data or not: CIP Vol 2 §3-4.2). A packet lost on the way (a gap) or a
duplicate (no new data) therefore never looks like slowness; only a target that sends less
often than it granted does. The median over at least a second of packets is compared with the
API: above ``SLOW_FACTOR`` × API the target is slow, reported once; at or below
``KEPT_FACTOR`` × API it keeps its grant again, reported once. Between the two, nothing changes
(no report flapping on a target that sits at the edge).
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass
from typing import Final

SLOW_FACTOR: Final = 1.5
"""The median interval above this many APIs: the target is slower than its grant."""
KEPT_FACTOR: Final = 1.25
"""The median interval at or below this many APIs: a slow target keeps its grant again."""
WINDOW_S: Final = 1.0
"""The shortest span of packets one verdict is made of."""
WINDOW_MIN_PACKETS: Final = 5
"""The fewest intervals one verdict is made of (at long RPIs, a window spans more than a
second)."""


@dataclass(frozen=True, slots=True)
class SlowTarget:
    """A target sending T→O less often than the API it granted."""

    granted_ms: float
    """The T→O API of the Forward Open reply."""
    sends_every_ms: float
    """The median interval between the packets it sent, over the window that found it slow."""

    def words(self, party: str = "target") -> str:
        """``the robot grants 2 ms but sends every 10 ms``."""
        return (
            f"the {party} grants {self.granted_ms:g} ms but sends every "
            f"{self.sends_every_ms:.3g} ms"
        )

    def kept_words(self, party: str = "target") -> str:
        """What clears it: ``the robot keeps its 2 ms grant again``."""
        return f"the {party} keeps its {self.granted_ms:g} ms grant again"


class PaceWatch:
    """One connection's T→O pace against its grant; ``packet`` per accepted T→O packet (new
    or duplicate, not stale): O(1) but for one sort of a window's intervals per window."""

    __slots__ = (
        "_api_s",
        "_intervals_s",
        "_last_at",
        "_last_seq",
        "_window_start",
        "found",
        "slow",
    )

    def __init__(self) -> None:
        self.slow: SlowTarget | None = None
        """What was last reported: slow (until the target keeps its grant again), or None."""
        self.found: SlowTarget | None = None
        """The last slowness found on this connection, kept once it clears (for its words)."""
        self._api_s = 0.0
        self._intervals_s: list[float] = []
        self._window_start: float | None = None
        self._last_at = 0.0
        self._last_seq: int | None = None

    def restart(self, api_us: int) -> None:
        """A new connection granted ``api_us``: nothing measured, nothing reported."""
        self.slow = self.found = None
        self._api_s = api_us / 1e6
        self._intervals_s.clear()
        self._window_start = None
        self._last_seq = None

    def packet(self, arrived_s: float, encap_seq: int) -> bool:
        """A T→O packet received at ``arrived_s`` (seconds, any clock), its encapsulation
        sequence number ``encap_seq``. Whether ``slow`` changed (a report to make)."""
        last_seq, self._last_seq = self._last_seq, encap_seq
        last_at, self._last_at = self._last_at, arrived_s
        if last_seq is None:
            self._window_start = arrived_s
            return False
        sent = (encap_seq - last_seq) & 0xFFFFFFFF
        if not 0 < sent < 0x80000000:  # not newer (the receive rules let none through)
            return False
        self._intervals_s.append((arrived_s - last_at) / sent)
        start = self._window_start
        if (
            start is None
            or arrived_s - start < WINDOW_S
            or len(self._intervals_s) < WINDOW_MIN_PACKETS
        ):
            return False
        median_s = statistics.median(self._intervals_s)
        self._intervals_s.clear()
        self._window_start = arrived_s
        if self.slow is None and median_s > SLOW_FACTOR * self._api_s:
            self.slow = self.found = SlowTarget(self._api_s * 1e3, median_s * 1e3)
            return True
        if self.slow is not None and median_s <= KEPT_FACTOR * self._api_s:
            self.slow = None
            return True
        return False


__all__ = ["KEPT_FACTOR", "SLOW_FACTOR", "WINDOW_S", "PaceWatch", "SlowTarget"]
