"""Layer: service. The ISA-18.2 alarm state machine (ANSI/ISA-18.2-2016 §11.4, "alarm state
transition diagram") with shelving. Pure: no I/O, no clock of its own (times are given).

States (the standard's letters):

- A ``normal``: not active, acknowledged;
- B ``active_unacknowledged``: the condition came; the operator has not acknowledged it;
- C ``active_acknowledged``: acknowledged, the condition is still there;
- D ``returned_unacknowledged``: the condition went before anyone acknowledged it;
- G ``suppressed``: the standard's "suppressed by design" (designed suppression): the
  condition came as the consequence of another alarm (its cause, ``suppressed_by``; the rules
  are ``consequences``), so it is recorded but not annunciated and needs no acknowledgement.

Transitions: A→B the condition comes; B→C acknowledge; B→D the condition goes; C→A the condition
goes; D→A acknowledge; D→B it comes again. Acknowledging in A, C or G changes nothing. A→G the
condition comes while its cause holds (the engine decides, ``process(..., suppressed_by=)``);
G→A the condition goes. Suppression is decided when the condition comes and lasts while it
holds: it never withdraws an alarm already annunciated, and a returned, unacknowledged alarm that
comes again (D→B) still needs its acknowledgement.

Shelving (§11.4.3: an operator's temporary suppression, with a reason and an expiry) is kept
beside the state: a shelved alarm still follows its condition (so unshelving shows the truth)
but is not annunciated; it is unshelved by the operator, when its time runs out, or when its
condition clears and comes again: a new occurrence is annunciated (active, unacknowledged), as
the shelving was meant for the occurrence the operator saw, not for the next one. Which alarms
may be shelved, and for how long, is ``shelving``'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Final


class AlarmState(StrEnum):
    NORMAL = "normal"
    ACTIVE_UNACKNOWLEDGED = "active_unacknowledged"
    ACTIVE_ACKNOWLEDGED = "active_acknowledged"
    RETURNED_UNACKNOWLEDGED = "returned_unacknowledged"
    SUPPRESSED = "suppressed"

    @property
    def active(self) -> bool:
        return self in _ACTIVE

    @property
    def acknowledged(self) -> bool:
        return self in _ACKNOWLEDGED


_ACTIVE: Final = frozenset(
    {AlarmState.ACTIVE_UNACKNOWLEDGED, AlarmState.ACTIVE_ACKNOWLEDGED, AlarmState.SUPPRESSED}
)
_ACKNOWLEDGED: Final = frozenset(
    {AlarmState.NORMAL, AlarmState.ACTIVE_ACKNOWLEDGED, AlarmState.SUPPRESSED}
)
"""Nothing to acknowledge: a suppressed alarm never needs it."""


class Transition(StrEnum):
    """Why an alarm's record changed (an ``alarm`` event's ``transition``)."""

    ACTIVATED = "activated"
    """The condition came (A→B, D→B; A→G suppressed by design)."""
    CLEARED = "cleared"
    """The condition went (B→D, C→A, G→A)."""
    ACKNOWLEDGED = "acknowledged"
    """The operator acknowledged (B→C, D→A)."""
    SHELVED = "shelved"
    UNSHELVED = "unshelved"
    SHELVE_EXPIRED = "shelve_expired"


# (state, condition active) → (new state, transition); a missing pair changes nothing.
PROCESS: Final[dict[tuple[AlarmState, bool], AlarmState]] = {
    (AlarmState.NORMAL, True): AlarmState.ACTIVE_UNACKNOWLEDGED,
    (AlarmState.ACTIVE_UNACKNOWLEDGED, False): AlarmState.RETURNED_UNACKNOWLEDGED,
    (AlarmState.ACTIVE_ACKNOWLEDGED, False): AlarmState.NORMAL,
    (AlarmState.RETURNED_UNACKNOWLEDGED, True): AlarmState.ACTIVE_UNACKNOWLEDGED,
    (AlarmState.SUPPRESSED, False): AlarmState.NORMAL,
}
ACKNOWLEDGE: Final[dict[AlarmState, AlarmState]] = {
    AlarmState.ACTIVE_UNACKNOWLEDGED: AlarmState.ACTIVE_ACKNOWLEDGED,
    AlarmState.RETURNED_UNACKNOWLEDGED: AlarmState.NORMAL,
}


class NothingToAcknowledgeError(Exception):
    """Acknowledging an alarm that is normal (nothing to acknowledge)."""


@dataclass(slots=True)
class AlarmStatus:
    """One alarm's record: its state, when it last came and went, who acknowledged and shelved
    it. Mutated only through its methods, which say what changed (or ``None``)."""

    state: AlarmState = AlarmState.NORMAL
    changed_at: float | None = None
    activated_at: float | None = None
    cleared_at: float | None = None
    acknowledged_at: float | None = None
    acknowledged_by: str | None = None
    ack_comment: str | None = None
    shelved_until: float | None = None
    shelved_at: float | None = None
    shelved_by: str | None = None
    shelve_reason: str | None = None
    value: float | bool | None = None
    """The watched value when the condition last came or went."""
    message: str | None = None
    """The condition in words at its last change ("J 3 motor temperature 81.2 °C")."""
    suppressed_by: str | None = None
    """The key of the alarm whose consequence this one's last activation was (state G while
    it holds); kept after it clears, as the acknowledgement is, until the next activation."""

    @property
    def shelved(self) -> bool:
        return self.shelved_until is not None

    def process(
        self, active: bool, time_s: float, *, suppressed_by: str | None = None
    ) -> Transition | None:
        """The condition is ``active`` (or not) now; ACTIVATED, CLEARED or ``None``.
        ``suppressed_by``: the key of the cause when the condition comes as its consequence
        (from normal only: A→G instead of A→B)."""
        new = PROCESS.get((self.state, active))
        if new is None:
            return None
        if active and self._cleared_while_shelved():
            self.unshelve(time_s)  # a new occurrence: annunciated again
        if active and suppressed_by is not None and self.state is AlarmState.NORMAL:
            new = AlarmState.SUPPRESSED
        self.state = new
        self.changed_at = time_s
        if active:
            self.activated_at = time_s
            self.cleared_at = None
            self.acknowledged_at = self.acknowledged_by = self.ack_comment = None
            self.suppressed_by = suppressed_by if new is AlarmState.SUPPRESSED else None
            return Transition.ACTIVATED
        self.cleared_at = time_s
        return Transition.CLEARED

    def _cleared_while_shelved(self) -> bool:
        cleared, shelved = self.cleared_at, self.shelved_at
        return (
            self.shelved_until is not None
            and cleared is not None
            and (shelved is None or cleared >= shelved)
        )

    def acknowledge(self, user: str, comment: str | None, time_s: float) -> Transition | None:
        """The operator acknowledges: ACKNOWLEDGED, ``None`` when already acknowledged (C), or
        ``NothingToAcknowledgeError`` in normal (A)."""
        if self.state is AlarmState.NORMAL:
            raise NothingToAcknowledgeError
        new = ACKNOWLEDGE.get(self.state)
        if new is None:
            return None
        self.state = new
        self.changed_at = time_s
        self.acknowledged_at = time_s
        self.acknowledged_by = user
        self.ack_comment = comment
        return Transition.ACKNOWLEDGED

    def shelve(self, user: str, reason: str, until_s: float, time_s: float) -> Transition:
        """Shelve (again: a new expiry and reason) until ``until_s``."""
        self.shelved_until = until_s
        self.shelved_at = time_s
        self.shelved_by = user
        self.shelve_reason = reason
        self.changed_at = time_s
        return Transition.SHELVED

    def unshelve(self, time_s: float, *, expired: bool = False) -> Transition | None:
        """End the shelving: UNSHELVED (or SHELVE_EXPIRED), ``None`` if it was not shelved."""
        if self.shelved_until is None:
            return None
        self.shelved_until = self.shelved_at = self.shelved_by = self.shelve_reason = None
        self.changed_at = time_s
        return Transition.SHELVE_EXPIRED if expired else Transition.UNSHELVED

    def expire(self, now_s: float) -> Transition | None:
        """SHELVE_EXPIRED once the shelving's time has run out, else ``None``."""
        until = self.shelved_until
        if until is not None and now_s >= until:
            return self.unshelve(now_s, expired=True)
        return None

    def to_json(self) -> dict[str, object]:
        return {
            "state": self.state.value,
            "changed_at": self.changed_at,
            "activated_at": self.activated_at,
            "cleared_at": self.cleared_at,
            "acknowledged_at": self.acknowledged_at,
            "acknowledged_by": self.acknowledged_by,
            "ack_comment": self.ack_comment,
            "shelved_until": self.shelved_until,
            "shelved_at": self.shelved_at,
            "shelved_by": self.shelved_by,
            "shelve_reason": self.shelve_reason,
            "value": self.value,
            "message": self.message,
            "suppressed_by": self.suppressed_by,
        }

    @classmethod
    def from_json(cls, data: dict[str, object]) -> AlarmStatus:
        """A record as ``to_json`` wrote it (a restart); unknown or bad values become the
        defaults rather than an error."""
        status = cls()
        try:
            status.state = AlarmState(str(data.get("state", "normal")))
        except ValueError:
            return status
        for name in (
            "changed_at",
            "activated_at",
            "cleared_at",
            "acknowledged_at",
            "shelved_until",
            "shelved_at",
        ):
            value = data.get(name)
            if isinstance(value, int | float) and not isinstance(value, bool):
                setattr(status, name, float(value))
        for name in (
            "acknowledged_by",
            "ack_comment",
            "shelved_by",
            "shelve_reason",
            "message",
            "suppressed_by",
        ):
            value = data.get(name)
            if isinstance(value, str):
                setattr(status, name, value)
        value = data.get("value")
        if isinstance(value, bool | int | float):
            status.value = value
        return status
