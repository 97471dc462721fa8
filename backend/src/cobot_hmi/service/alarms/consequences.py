"""Layer: service. Designed suppression (ISA-18.2 "suppressed by design"): which built-in
alarms are consequences of which, so one event in the cell asks for one acknowledgement. Pure.

An alarm whose condition comes while one of its causes is active (or, where the rule says so,
within ``alarm_consequence_window_s`` after that cause cleared) is a consequence: it enters the
``suppressed`` state (``state.AlarmState.SUPPRESSED``), is recorded in the history and sent as
an event like any other, names its cause (``suppressed_by``), but is not annunciated and needs
no acknowledgement; it returns to normal when its own condition goes.

The rules, and why each is a consequence rather than news to the operator ("after": also
within the window after the cause cleared):

- ``emergency_stop`` → ``protective_stop`` (while active): a robot may set its safety-stop
  flag with the emergency stop's; ``safe_off`` (after): resetting the stop takes the robot
  through SAFE_OFF (servo off) before standby. The operator was told about the stop.
- ``protective_stop`` → ``safe_off`` (after): the same reset after a protective stop.
- ``connection_lost`` → ``forward_open_refused`` (while active): a refused reconnection says
  nothing new once the link is down; ``packet_loss`` (after): the gaps around the loss.
- ``forward_open_refused`` → ``connection_lost`` (while active): a robot refusing the
  connection is not connected, by definition; ``packet_loss`` (after).

A protective stop a few seconds after an emergency stop's reset is news (the rule is "while
active"); SAFE_OFF long after a reset is an error of its own (outside the window).

Of two possible causes the most recent is named (an active one before one that cleared, else
the one that cleared last): a SAFE_OFF after a protective stop's reset is the protective
stop's, though an emergency stop cleared a few seconds before that is still within its window.

A cause that is itself suppressed does not suppress others: the cause named is always an alarm
that was annunciated (the root). Suppression is decided when the consequence comes: an alarm
already annunciated before its cause came stays annunciated (nothing the operator was told is
withdrawn).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Final

from cobot_hmi.service.alarms import definitions as d
from cobot_hmi.service.alarms.state import AlarmStatus

CONSEQUENCES: Final[Mapping[str, Mapping[str, bool]]] = {
    d.EMERGENCY_STOP: {d.PROTECTIVE_STOP: False, d.SAFE_OFF: True},
    d.PROTECTIVE_STOP: {d.SAFE_OFF: True},
    d.CONNECTION_LOST: {d.FORWARD_OPEN_REFUSED: False, d.PACKET_LOSS: True},
    d.FORWARD_OPEN_REFUSED: {d.CONNECTION_LOST: False, d.PACKET_LOSS: True},
}
"""Cause → {consequence: also within the window after the cause cleared} (the module
docstring says why)."""


def _causes() -> dict[str, tuple[tuple[str, bool], ...]]:
    out: dict[str, list[tuple[str, bool]]] = {}
    for cause, consequences in CONSEQUENCES.items():
        for consequence, after in consequences.items():
            out.setdefault(consequence, []).append((cause, after))
    return {key: tuple(causes) for key, causes in out.items()}


CAUSES: Final[Mapping[str, tuple[tuple[str, bool], ...]]] = _causes()
"""Consequence → its possible causes (and whether the window after them counts), in the order
``CONSEQUENCES`` names them (the first that holds is named)."""


def _recency(
    status: AlarmStatus, after: bool, time_s: float, window_s: float
) -> tuple[bool, float] | None:
    """How recent a cause is for a consequence coming at ``time_s`` (greater is more recent:
    (active, when it came or cleared)), or ``None`` when it is no cause of it now. An active
    cause is more recent than any cleared one (it holds now; among several, the one that came
    last counts); a cleared one counts from when it cleared."""
    if status.suppressed_by is not None:
        return None  # itself a consequence (now, or when it last came): not the root
    if status.state.active:
        return (True, math.inf if status.activated_at is None else status.activated_at)
    # Frame alarms run on receive times, connection alarms on the clock: both epoch seconds,
    # not ordered to the millisecond, so the window counts either way.
    cleared = status.cleared_at
    if after and cleared is not None and abs(time_s - cleared) <= window_s:
        return (False, cleared)
    return None


def cause_of(
    key: str, statuses: Mapping[str, AlarmStatus], time_s: float, window_s: float
) -> str | None:
    """The key of the cause whose consequence alarm ``key`` is if its condition comes at
    ``time_s``, or ``None`` (it is news: annunciate it). Of several possible causes the most
    recent is named: a SAFE_OFF after a protective stop's reset is the protective stop's, even
    with an emergency stop cleared a few seconds before it (ties: ``CONSEQUENCES``'s order)."""
    best: tuple[tuple[bool, float], str] | None = None
    for cause, after in CAUSES.get(key, ()):
        status = statuses.get(cause)
        recency = None if status is None else _recency(status, after, time_s, window_s)
        if recency is not None and (best is None or recency > best[0]):
            best = (recency, cause)
    return None if best is None else best[1]
