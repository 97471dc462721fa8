"""The receive-interval window's figures (``scanner/stats.py``) against the definition: mean,
the median and p99 at ranks ⌊n/2⌋ and ⌊0.99·n⌋ of the sorted window, max; only the newest
``size`` intervals count."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cobot_hmi.scanner.stats import IntervalWindow

intervals = st.lists(
    st.floats(min_value=0.0, max_value=1e4, allow_nan=False, allow_infinity=False),
    min_size=1,
    max_size=300,
)


@given(values=intervals, size=st.integers(min_value=1, max_value=256))
def test_figures_follow_their_definition(values: list[float], size: int) -> None:
    window = IntervalWindow(size)
    for value in values:
        window.add(value)
    kept = sorted(values[-size:])
    n = len(kept)
    figures = window.figures()
    assert figures.count == n
    assert figures.mean_ms == pytest.approx(sum(kept) / n, rel=1e-9, abs=1e-9)
    assert figures.p50_ms == kept[n // 2]
    assert figures.p99_ms == kept[min(n - 1, int(n * 0.99))]
    assert figures.max_ms == kept[-1]


def test_an_empty_window_has_no_figures() -> None:
    window = IntervalWindow()
    assert window.figures().count == 0
    assert window.figures().p99_ms is None
    window.add(10.0)
    window.clear()
    assert window.figures().mean_ms is None


def test_one_late_interval_in_a_hundred_is_the_p99() -> None:
    window = IntervalWindow()
    for i in range(1000):
        window.add(30.0 if i % 100 == 0 else 10.0)
    figures = window.figures()
    assert figures.p50_ms == 10.0
    assert figures.p99_ms == 30.0  # rank 990 of 1000: the 10 late ones are ranks 990–999
    assert figures.max_ms == 30.0


@given(
    chunks=st.lists(intervals, min_size=1, max_size=8),
    size=st.integers(min_value=1, max_value=64),
    bounded=st.booleans(),
)
def test_figures_asked_between_additions_keep_to_the_newest(
    chunks: list[list[float]], size: int, bounded: bool
) -> None:
    """Figures asked (or the window bounded, as the owner does per batch) between additions:
    the same figures as of the newest ``size`` intervals, whatever the ring's wrap."""
    window = IntervalWindow(size)
    added: list[float] = []
    for chunk in chunks:
        for value in chunk:
            window.add(value)
        added += chunk
        if bounded:
            window.bound()
        kept = sorted(added[-size:])
        n = len(kept)
        figures = window.figures()
        assert figures.count == n
        assert figures.p50_ms == kept[n // 2]
        assert figures.p99_ms == kept[min(n - 1, int(n * 0.99))]
        assert figures.max_ms == kept[-1]
        assert figures.mean_ms == pytest.approx(sum(kept) / n, rel=1e-9, abs=1e-9)


def test_an_unasked_window_holds_at_most_a_window_of_additions() -> None:
    window = IntervalWindow(100)
    for i in range(10_000):
        window.add(float(i))
        window.bound()
    assert len(window._added) < 100
    assert window.figures().max_ms == 9999.0
    assert window.figures().count == 100
