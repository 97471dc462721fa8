"""Layer: enip (pure). Imports nothing of the project.

The receive rules of a class 1 consumer, once for both roles (the target's O→T and the
originator's T→O): what a packet's two sequence numbers say about it, against the last packet
accepted on the same connection. docs/protocol.md "Cyclic packets" describes them in words.

Two counters ride in every class 1 packet:

- the **encapsulation sequence number** (UDINT, Sequenced Address item 0x8002), raised by one
  for every packet the producer sends. Numbers compare in sequence-number arithmetic (CIP
  Vol 2 §3-4.2): a consumer keeps only a packet whose number is *newer* than the last one it
  kept; an equal or older number is a duplicate or a reordered datagram, and is discarded;
- the **CIP sequence count** (UINT, first in the Connected Data item 0x00B1), which transport
  class 1 raises when the producer has *new data* (CIP Vol 1 §3-4, Connection object,
  transport class 1). The same count again means "no new data": the packet proves the
  producer alive (it feeds the connection's watchdog) but is not delivered. A count ahead by
  more than one means packets were lost: ``ahead - 1`` of them.

Both compare in half-range wrapping arithmetic: a number up to half the range ahead is newer,
one up to half the range behind is older. A CIP count that goes *backwards* while the
encapsulation number moves on cannot come from a producer keeping the rules: the packet is
discarded as stale and changes nothing (it does not feed the watchdog either, so a producer
stuck that way times out rather than holding a connection that carries nothing).

API (stable: both roles use it)::

    tracker = SequenceTracker()            # one per connection direction consumed
    verdict = tracker.accept(encap_seq, cip_seq)
    if verdict is NEW:        # new data; tracker.missed packets were lost before it
    elif verdict is DUPLICATE:  # alive (feed the watchdog), no new data
    else:                     # STALE: drop, nothing changed
    tracker.reset()           # forget everything (a new connection)

``cip_seq`` is ``None`` for a packet without a CIP sequence count (a zero-size heartbeat): it is
NEW (alive, nothing missed) whenever its encapsulation number is newer. ``accept`` allocates
nothing: the verdicts are the three members of :class:`Verdict`.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Final


class Verdict(IntEnum):
    """What a class 1 packet is, against the last one accepted."""

    NEW = 0
    """New data (or the first packet): deliver it; ``SequenceTracker.missed`` says how many
    packets were lost just before it."""
    DUPLICATE = 1
    """The same CIP sequence count as the last one: the producer is alive, the data is not
    new."""
    STALE = 2
    """An encapsulation sequence number not newer than the last one kept, or a CIP sequence
    count that went backwards: discard it; the tracker did not change."""


NEW: Final = Verdict.NEW
DUPLICATE: Final = Verdict.DUPLICATE
STALE: Final = Verdict.STALE

_HALF32: Final = 0x8000_0000
_HALF16: Final = 0x8000


class SequenceTracker:
    """The sequence state of one consumed class 1 stream (CIP Vol 2 §3-4.2, Vol 1 §3-4)."""

    __slots__ = ("last_cip_seq", "last_encap_seq", "missed")

    def __init__(self) -> None:
        self.last_encap_seq: int | None = None
        """The encapsulation sequence number of the last packet accepted (NEW or DUPLICATE)."""
        self.last_cip_seq: int | None = None
        """The CIP sequence count of the last NEW packet that had one."""
        self.missed = 0
        """After a NEW verdict: how many packets the CIP sequence count skipped; else 0."""

    def reset(self) -> None:
        """Forget the stream: the next packet is NEW whatever its numbers."""
        self.last_encap_seq = None
        self.last_cip_seq = None
        self.missed = 0

    def accept(self, encap_seq: int, cip_seq: int | None) -> Verdict:
        """Classify one packet and, unless it is STALE, remember its numbers."""
        last_encap = self.last_encap_seq
        if last_encap is not None:
            ahead32 = (encap_seq - last_encap) & 0xFFFF_FFFF
            if ahead32 == 0 or ahead32 >= _HALF32:
                self.missed = 0
                return STALE
        last_cip = self.last_cip_seq
        if cip_seq is None or last_cip is None:
            self.last_encap_seq = encap_seq
            if cip_seq is not None:
                self.last_cip_seq = cip_seq
            self.missed = 0
            return NEW
        ahead16 = (cip_seq - last_cip) & 0xFFFF
        if ahead16 == 0:
            self.last_encap_seq = encap_seq
            self.missed = 0
            return DUPLICATE
        if ahead16 >= _HALF16:
            self.missed = 0
            return STALE
        self.last_encap_seq = encap_seq
        self.last_cip_seq = cip_seq
        self.missed = ahead16 - 1
        return NEW


__all__ = ["DUPLICATE", "NEW", "STALE", "SequenceTracker", "Verdict"]
