"""Layer: service (Sparkplug). Pure: report by exception, what a DDATA must carry.

Discrete metrics (bits, coded values, the robot state, the version) are compared frame by frame
over every frame the hub delivered since the last report, so each transition is reported with
its own frame's timestamp, even one that came and went between two reports: they are never
decimated away. Analog metrics (``REAL``) are compared once per report, newest frame against the
value last reported, and sent when they moved by their deadband or more (absolute, in the
field's unit; a deadband of 0 sends any change). The edge node calls this at most at its
maximum rate per robot, so analog values are sampled at that rate.

Imports only the codec, ``catalogue`` and ``payload``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import chain
from operator import itemgetter
from typing import Any, Final

from cobot_hmi.codec import Frame
from cobot_hmi.service.robots.frame_notifier import FrameRecord
from cobot_hmi.sparkplug.catalogue import Catalogue
from cobot_hmi.sparkplug.payload import MetricValue

Change = tuple[int, MetricValue, int]
"""``(metric offset, value, timestamp ms)``."""


_FRAME: Final = itemgetter(2)
"""A ``FrameRecord``'s frame."""


def _getter(fields: list[str]) -> Any:
    """The fields' values of a frame, as a tuple: by position (a ``Frame`` is a named tuple;
    ``itemgetter`` is a quarter cheaper than ``attrgetter``, and runs ten times per tick)."""
    getter = itemgetter(*(Frame._fields.index(f) for f in fields))
    if len(fields) == 1:
        return lambda frame: (getter(frame),)
    return getter


def moved(new: float, old: float, deadband: float) -> bool:
    """Whether an analog value is reported: by the deadband or more, or into/out of NaN."""
    new_nan, old_nan = math.isnan(new), math.isnan(old)
    if new_nan or old_nan:
        return new_nan != old_nan
    if deadband <= 0:
        return new != old
    return abs(new - old) >= deadband


_ANY_CHANGE: Final = math.ulp(0.0)
"""The least step a deadband of 0 (or less) sends: between two numbers that are not NaN,
``abs(new - old) >= ulp(0)`` exactly when ``new != old`` (the difference of two different
floats is never 0, gradual underflow; of two equal infinities NaN, of unequal ones infinite)."""


def threshold(deadband: float) -> float:
    """What ``abs(new - old)`` must reach for ``moved`` (NaN aside): the deadband, or for one
    of 0 or less any change (a NaN deadband stays NaN: nothing moves by it, as in ``moved``)."""
    return _ANY_CHANGE if deadband <= 0 else deadband


class Reporter:
    """One robot's last reported values and the changes since (module docstring)."""

    def __init__(self, catalogue: Catalogue) -> None:
        spans = catalogue.discrete_spans
        self._discrete_spans = spans
        self._discrete = _getter([s.field for s in spans])
        self._analog = _getter([s.field for s in catalogue.analog_spans])
        self.analog_offsets = [
            span.first + i for span in catalogue.analog_spans for i in range(span.count)
        ]
        """The metric offset of each analog value, in the order ``analog_moved`` gives them."""
        self._deadbands = catalogue.analog_deadbands()
        self._thresholds = [threshold(d) for d in self._deadbands]
        self._analog_positions = range(len(self._deadbands))
        self._last_discrete: tuple[Any, ...] | None = None
        self._reported_analog: list[float] = []
        self.transitions = 0
        """Discrete transitions reported (all of them)."""

    def baseline(self, frame: Frame) -> None:
        """A birth reported ``frame`` whole: changes are counted from it."""
        self._last_discrete = self._discrete(frame)
        self._reported_analog = self._flat_analog(frame)

    def _flat_analog(self, frame: Frame) -> list[float]:
        return list(chain.from_iterable(self._analog(frame)))

    def discrete_changes(self, items: Sequence[FrameRecord]) -> list[Change]:
        """Every discrete transition across ``items`` (oldest first), each at its frame's time."""
        changes: list[Change] = []
        last = self._last_discrete
        seen = list(map(self._discrete, map(_FRAME, items)))
        if last is not None and seen.count(last) == len(seen):
            return changes  # the common case, every frame compared in one call
        for record, values in zip(items, seen, strict=True):
            if last is None:
                last = values
                continue
            if values != last:
                stamp = int(record[1] * 1000)
                for span, new, old in zip(self._discrete_spans, values, last, strict=True):
                    if new == old:
                        continue
                    if span.scalar:
                        changes.append((span.first, new, stamp))
                        continue
                    for i, (a, b) in enumerate(zip(new, old, strict=True)):
                        if a != b:
                            changes.append((span.first + i, a, stamp))
                last = values
        self._last_discrete = last
        self.transitions += len(changes)
        return changes

    def analog_moved(self, frame: Frame) -> tuple[list[float], list[int]]:
        """The analog values of ``frame`` and which of them (their positions in it, see
        ``analog_offsets``) moved by their deadband since last reported: reported from now."""
        current = self._flat_analog(frame)
        reported = self._reported_analog
        if not reported:
            self._reported_analog = current
            return current, []
        if math.isnan(sum(current) + sum(reported)):  # a NaN (or infinities of both signs)
            moved_at = [
                i
                for i, new, old, deadband in zip(
                    self._analog_positions, current, reported, self._deadbands, strict=True
                )
                if moved(new, old, deadband)
            ]
        else:
            # No NaN: ``moved`` is one comparison, here in a comprehension (a call of ``moved``
            # per value was the most of a tick's rbe time, py-spy).
            moved_at = [
                i
                for i, new, old, at_least in zip(
                    self._analog_positions, current, reported, self._thresholds, strict=True
                )
                if abs(new - old) >= at_least
            ]
        for i in moved_at:
            reported[i] = current[i]
        return current, moved_at
