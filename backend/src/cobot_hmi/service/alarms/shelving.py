"""Layer: service. Which alarms may be shelved and for how long (ANSI/ISA-18.2-2016 §11.4.3,
shelving: a temporary suppression by an operator, with a reason and an expiry; the alarm
philosophy sets its limits). Pure: imports the alarms' definitions only.

- The safety stops (emergency stop, protective stop) and every critical alarm are never
  shelved: the most urgent alarms stay annunciated whatever an operator wants.
- Every other priority has a longest shelving of its own (``alarm_shelve_max_high_s`` …),
  never over ``alarm_shelve_max_s`` (the longest for any alarm).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Final

from cobot_hmi.service.alarms import definitions as d
from cobot_hmi.service.alarms.definitions import AlarmDefinition, Priority

NEVER_SHELVED: Final = frozenset({d.EMERGENCY_STOP, d.PROTECTIVE_STOP})
"""The safety stops: never shelved, whatever their priority."""

DEFAULT_MAX_S: Final = {
    Priority.HIGH: 3600.0,
    Priority.MEDIUM: 4 * 3600.0,
    Priority.LOW: 8 * 3600.0,
    Priority.ADVISORY: 7 * 86_400.0,
}
"""Each priority's longest shelving unless the settings say otherwise, s."""


class AlarmRefusedError(ValueError):
    """An operator's request that does not apply (acknowledge a normal alarm, a bad shelving)."""


class NotShelvableError(AlarmRefusedError):
    """The alarm is one that is never shelved (a safety stop, a critical alarm)."""


def _duration_words(seconds: float) -> str:
    if seconds >= 3600 and seconds % 3600 == 0:
        return f"{seconds / 3600:g} h"
    if seconds >= 60 and seconds % 60 == 0:
        return f"{seconds / 60:g} min"
    return f"{seconds:g} s"


@dataclass(frozen=True, slots=True)
class ShelvingRules:
    """The longest shelving of each priority (a priority without one is never shelved) and
    the longest of any alarm (``cap_s``)."""

    cap_s: float
    max_by_priority_s: Mapping[Priority, float] = field(default_factory=lambda: DEFAULT_MAX_S)

    def refusal(self, definition: AlarmDefinition) -> str | None:
        """Why this alarm is never shelved, or ``None``."""
        if definition.key in NEVER_SHELVED:
            return (
                f"{definition.name} is a safety stop: it cannot be shelved (ISA-18.2: the "
                "highest-priority alarms stay annunciated)"
            )
        if definition.priority not in self.max_by_priority_s:
            return (
                f"{definition.name} is a {definition.priority.value} alarm: it cannot be shelved "
                "(ISA-18.2: the highest-priority alarms stay annunciated)"
            )
        return None

    def max_s(self, definition: AlarmDefinition) -> float | None:
        """The longest this alarm may be shelved, s (``None``: never)."""
        if self.refusal(definition) is not None:
            return None
        return min(self.max_by_priority_s[definition.priority], self.cap_s)

    def setting_of(self, definition: AlarmDefinition) -> str:
        """The setting that bounds this alarm's shelving (named in a refusal)."""
        own = self.max_by_priority_s.get(definition.priority)
        if own is not None and own <= self.cap_s:
            if definition.priority is Priority.ADVISORY:  # no setting of its own
                return "the advisory priority's own maximum"
            return f"alarm_shelve_max_{definition.priority.value}_s"
        return "alarm_shelve_max_s"

    def check(self, definition: AlarmDefinition, duration_s: float) -> None:
        """``NotShelvableError`` for an alarm never shelved, ``AlarmRefusedError`` naming the
        maximum for a duration outside (0, maximum]."""
        refusal = self.refusal(definition)
        if refusal is not None:
            raise NotShelvableError(refusal)
        longest = self.max_s(definition)
        assert longest is not None
        if not 0 < duration_s <= longest:
            raise AlarmRefusedError(
                f"a {definition.priority.value} alarm is shelved for more than 0 and at most "
                f"{longest:g} s ({_duration_words(longest)}, {self.setting_of(definition)})"
            )
