"""Layer: service. When a frame makes an alarm's condition true: robot states and flags, limits
on numbers (high, low, deadband), bits, each with an on-delay and an off-delay. Pure.

These run on every frame of every robot (``engine.AlarmEngine.observe``), so a frame that changes
nothing costs a few attribute reads and comparisons and allocates nothing: the element is read
from the frame as it is (no copy), the limits' clearing points (``high − deadband``,
``low + deadband``) are computed once, and arithmetic on times happens only while a delay
runs. ``update`` answers ``UNCHANGED``, ``CAME`` or ``WENT`` (small ints, never an object).

Deadband (ISA-18.2 §10.4.1, hysteresis): an active high alarm clears only once the value is
back below ``high − deadband`` (a low one above ``low + deadband``), so a value hovering at
the limit does not chatter. On-delay: the condition must hold this long (frame time) before the
alarm comes; off-delay: it must be gone this long before the alarm clears.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.service.labels import flag_words, named, robot_state_words, value_words

UNCHANGED: Final = 0
CAME: Final = 1
WENT: Final = 2


class Condition:
    """A condition with on- and off-delays; subclasses say whether it holds in a frame."""

    __slots__ = ("_since", "active", "off_delay_s", "on_delay_s")

    def __init__(self, *, on_delay_s: float = 0.0, off_delay_s: float = 0.0) -> None:
        self.on_delay_s = on_delay_s
        self.off_delay_s = off_delay_s
        self.active = False
        """The condition as the alarm sees it (after the delays)."""
        self._since: float | None = None
        """Frame time since when the raw condition differs from ``active`` (a delay runs)."""

    @property
    def delaying(self) -> bool:
        """An on- or off-delay runs: the same frame later may change the condition."""
        return self._since is not None

    def holds(self, frame: Frame) -> bool:  # pragma: no cover - abstract
        raise NotImplementedError

    def update(self, frame: Frame, time_s: float) -> int:
        """The frame at ``time_s``: ``CAME``, ``WENT`` or ``UNCHANGED`` (the hot path)."""
        raw = self.holds(frame)
        if raw is self.active:
            self._since = None
            return UNCHANGED
        return self._settle(raw, time_s)

    def _settle(self, raw: bool, time_s: float) -> int:
        """The raw condition differs from ``active``: run the delay, or change."""
        since = self._since
        if since is None:
            self._since = since = time_s
        if time_s - since < (self.on_delay_s if raw else self.off_delay_s):
            return UNCHANGED
        self.active = raw
        self._since = None
        return CAME if raw else WENT

    def restore(self, active: bool) -> None:
        """Start from ``active`` (a restart: the persisted alarm's condition)."""
        self.active = active
        self._since = None

    def describe(self, frame: Frame, tags: Mapping[str, str]) -> tuple[float | bool | None, str]:
        """The watched value and the condition in words (only when something changed)."""
        raise NotImplementedError  # pragma: no cover - abstract


class StateCondition(Condition):
    """The robot is in one state, or (``flag``) shows a flag that means the same."""

    __slots__ = ("flag", "state", "state_name")

    def __init__(self, state: int, state_name: str, flag: str | None = None) -> None:
        super().__init__()
        self.state = state
        self.state_name = state_name
        self.flag = flag

    def holds(self, frame: Frame) -> bool:
        if frame.robot_state == self.state:
            return True
        return self.flag is not None and getattr(frame, self.flag) is True

    def update(self, frame: Frame, time_s: float) -> int:
        # ``holds`` written out (one call per frame, not two; bench/alarms).
        flag = self.flag
        raw = frame.robot_state == self.state or (flag is not None and getattr(frame, flag) is True)
        if raw is self.active:
            self._since = None
            return UNCHANGED
        return self._settle(raw, time_s)

    def describe(self, frame: Frame, tags: Mapping[str, str]) -> tuple[float | bool | None, str]:
        """The state in words, whether the alarm came ("robot state Emergency stop, Emergency
        stopped flag set") or went ("robot state now Safe off (servo off)"): never a number."""
        state = robot_state_words(frame.robot_state)
        if not self.active:
            return frame.robot_state, f"robot state now {state}"
        words = f"robot state {state}"
        if self.flag is not None and getattr(frame, self.flag):
            words += f", {flag_words(self.flag, True)}"
        return frame.robot_state, words


class ElementCondition(Condition):
    """A condition on one element of the frame (``field``, ``index``; a scalar: no index)."""

    __slots__ = ("field", "index", "key")

    def __init__(
        self, key: str, field: str, index: int | None, *, on_delay_s: float, off_delay_s: float
    ) -> None:
        super().__init__(on_delay_s=on_delay_s, off_delay_s=off_delay_s)
        self.key = key
        self.field = field
        self.index = index

    def value(self, frame: Frame) -> object:
        value = getattr(frame, self.field)
        return value if self.index is None else value[self.index]

    def describe(self, frame: Frame, tags: Mapping[str, str]) -> tuple[float | bool | None, str]:
        value = self.value(frame)
        number: float | bool | None
        if isinstance(value, bool):
            number = value
        elif isinstance(value, int | float):
            number = float(value) if math.isfinite(value) else None
        else:
            number = None
        analog_type = None
        if self.field in ("analog_input", "analog_output") and self.index is not None:
            analog_type = getattr(frame, f"{self.field}_type")[self.index]
        return number, f"{named(self.key, tags)} = {value_words(self.key, value, analog_type)}"


class LimitCondition(ElementCondition):
    """A number above ``high`` or below ``low`` (either may be absent), with a deadband."""

    __slots__ = ("_high_clear", "_low_clear", "deadband", "high", "low")

    def __init__(
        self,
        key: str,
        field: str,
        index: int | None,
        *,
        high: float | None,
        low: float | None,
        deadband: float = 0.0,
        on_delay_s: float = 0.0,
        off_delay_s: float = 0.0,
    ) -> None:
        super().__init__(key, field, index, on_delay_s=on_delay_s, off_delay_s=off_delay_s)
        self.high = high
        self.low = low
        self.deadband = deadband
        self._high_clear = None if high is None else high - deadband
        self._low_clear = None if low is None else low + deadband

    def update(self, frame: Frame, time_s: float) -> int:
        # ``holds`` written out here: one Python call per limit and frame instead of two (the
        # hot path; bench/alarms). The two must say the same (tests/test_alarms_units.py).
        value = getattr(frame, self.field)
        index = self.index
        if index is not None:
            value = value[index]
        active = self.active
        if active:
            high_clear = self._high_clear
            if high_clear is not None and not value <= high_clear:
                raw = True
            else:
                low_clear = self._low_clear
                raw = low_clear is not None and not value >= low_clear
        else:
            high = self.high
            if high is not None and value > high:
                raw = True
            else:
                low = self.low
                raw = low is not None and value < low
        if raw is active:
            self._since = None
            return UNCHANGED
        return self._settle(raw, time_s)

    def holds(self, frame: Frame) -> bool:
        value = getattr(frame, self.field)
        if self.index is not None:
            value = value[self.index]
        if self.active:
            # Active until back inside both limits by the deadband (NaN stays active).
            high_clear = self._high_clear
            if high_clear is not None and not value <= high_clear:
                return True
            low_clear = self._low_clear
            return low_clear is not None and not value >= low_clear
        high = self.high
        if high is not None and value > high:
            return True
        low = self.low
        return low is not None and value < low


class BitCondition(ElementCondition):
    """A bit (or flag) that has the value ``active_when``."""

    __slots__ = ("active_when",)

    def __init__(
        self,
        key: str,
        field: str,
        index: int | None,
        *,
        active_when: bool = True,
        on_delay_s: float = 0.0,
        off_delay_s: float = 0.0,
    ) -> None:
        super().__init__(key, field, index, on_delay_s=on_delay_s, off_delay_s=off_delay_s)
        self.active_when = active_when

    def holds(self, frame: Frame) -> bool:
        value = getattr(frame, self.field)
        if self.index is not None:
            value = value[self.index]
        return bool(value == self.active_when)

    def update(self, frame: Frame, time_s: float) -> int:
        # ``holds`` written out (one call per frame, not two; bench/alarms).
        value = getattr(frame, self.field)
        index = self.index
        if index is not None:
            value = value[index]
        raw = value is self.active_when or value == self.active_when
        if raw is self.active:
            self._since = None
            return UNCHANGED
        return self._settle(raw, time_s)
