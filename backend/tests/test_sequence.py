"""The class 1 receive rules (``enip.sequence``): new, duplicate, stale and gaps, across the
wrap of both counters (CIP Vol 2 §3-4.2, Vol 1 §3-4; docs/protocol.md "Cyclic packets")."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from cobot_hmi.enip.sequence import DUPLICATE, NEW, STALE, SequenceTracker, Verdict

u32 = st.integers(0, 0xFFFF_FFFF)
u16 = st.integers(0, 0xFFFF)


def test_first_packet_is_new_then_the_rules_apply() -> None:
    tracker = SequenceTracker()
    assert tracker.accept(10, 100) is NEW and tracker.missed == 0
    assert tracker.accept(11, 101) is NEW and tracker.missed == 0
    assert tracker.accept(12, 101) is DUPLICATE  # alive, no new data
    assert tracker.accept(12, 102) is STALE  # the same encapsulation number again
    assert tracker.accept(11, 102) is STALE  # an older one (reordered)
    assert tracker.accept(13, 100) is STALE  # CIP count backwards
    assert (tracker.last_encap_seq, tracker.last_cip_seq) == (12, 101)  # stale changed nothing
    assert tracker.accept(14, 105) is NEW and tracker.missed == 3
    assert tracker.accept(15, 106) is NEW and tracker.missed == 0


def test_heartbeats_without_a_count_are_new_while_their_number_moves_on() -> None:
    tracker = SequenceTracker()
    assert tracker.accept(1, None) is NEW
    assert tracker.accept(2, None) is NEW
    assert tracker.accept(2, None) is STALE
    assert tracker.last_cip_seq is None


def test_reset_forgets_the_stream() -> None:
    tracker = SequenceTracker()
    assert tracker.accept(100, 5) is NEW
    tracker.reset()
    assert tracker.accept(1, 1) is NEW and tracker.missed == 0


def test_verdicts_are_the_enum_members() -> None:
    assert list(Verdict) == [NEW, DUPLICATE, STALE]


@given(u32, u16, st.integers(1, 0x7FFF), st.integers(1, 1000))
def test_a_count_ahead_is_new_with_its_gap_across_the_wrap(
    encap: int, cip: int, ahead: int, encap_step: int
) -> None:
    tracker = SequenceTracker()
    assert tracker.accept(encap, cip) is NEW
    next_encap = (encap + encap_step) & 0xFFFF_FFFF
    assert tracker.accept(next_encap, (cip + ahead) & 0xFFFF) is NEW
    assert tracker.missed == ahead - 1
    assert tracker.last_cip_seq == (cip + ahead) & 0xFFFF


@given(u32, u16, st.integers(1, 0x8000))
def test_a_count_behind_is_stale_across_the_wrap(encap: int, cip: int, behind: int) -> None:
    tracker = SequenceTracker()
    tracker.accept(encap, cip)
    assert tracker.accept((encap + 1) & 0xFFFF_FFFF, (cip - behind) & 0xFFFF) is STALE
    assert (tracker.last_encap_seq, tracker.last_cip_seq) == (encap, cip)


@given(u32, u16, st.integers(0, 0x8000_0000))
def test_an_encapsulation_number_not_newer_is_stale_across_the_wrap(
    encap: int, cip: int, behind: int
) -> None:
    tracker = SequenceTracker()
    tracker.accept(encap, cip)
    assert tracker.accept((encap - behind) & 0xFFFF_FFFF, (cip + 1) & 0xFFFF) is STALE


@given(u32, u16, st.lists(st.integers(0, 3), min_size=1, max_size=200))
def test_a_stream_with_losses_and_repeats_sums_its_gaps(
    encap: int, cip: int, steps: list[int]
) -> None:
    """A producer keeping the rules: every packet a new encapsulation number; the CIP count
    repeats (0), moves on (1) or skips (2, 3). The verdicts add up to what was skipped."""
    tracker = SequenceTracker()
    tracker.accept(encap, cip)
    missed = duplicates = 0
    for step in steps:
        encap = (encap + 1) & 0xFFFF_FFFF
        cip = (cip + step) & 0xFFFF
        verdict = tracker.accept(encap, cip)
        if step == 0:
            assert verdict is DUPLICATE
            duplicates += 1
        else:
            assert verdict is NEW
            missed += tracker.missed
    assert missed == sum(s - 1 for s in steps if s > 1)
    assert duplicates == steps.count(0)
