"""Layer: service. Alarms at a glance: per robot (``models.AlarmSummary``: counts by priority,
the most urgent alarm that needs a person, in the service's words) and for the whole cell
(``models.CellAlarmSummary``), for the fleet tiles, the robot switcher's mark and a banner line
naming another robot. Pure: reads alarm records, never changes them.

"Annunciated" is what a banner shows: an alarm that is not normal, not shelved and not
suppressed by design (``consequences``). The most urgent of them is chosen as the panel's
banner chooses (``frontend/src/lib/alarms/alarms.ts`` ``compareAlarms``): active before returned,
then by priority, then the newest change.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Final

from cobot_hmi.service.alarms.definitions import AlarmDefinition, Priority
from cobot_hmi.service.alarms.state import AlarmState, AlarmStatus

Entry = tuple[AlarmDefinition, AlarmStatus]
Summary = dict[str, object]

BRIEF_KEYS: Final = (
    "id",
    "robot",
    "key",
    "name",
    "priority",
    "priority_rank",
    "colour",
    "state",
    "active",
    "label",
    "tag",
    "message",
    "activated_at",
    "changed_at",
)
"""The fields of ``models.AlarmBrief``: an ``Alarm``'s, enough to name it on a banner line."""

_COUNTED: Final = ("annunciated", "active", "unacknowledged")


def annunciated(status: AlarmStatus) -> bool:
    """Whether a person must see it: not normal, not shelved, not suppressed by design."""
    return status.state not in (AlarmState.NORMAL, AlarmState.SUPPRESSED) and not status.shelved


def urgency(alarm: dict[str, object]) -> tuple[bool, int, float]:
    """Sort key of an ``Alarm`` (or ``AlarmBrief``), most urgent first: active before
    returned, then priority, then the newest change."""
    rank, changed = alarm["priority_rank"], alarm["changed_at"]
    return (
        not alarm["active"],
        rank if isinstance(rank, int) else 3,
        -changed if isinstance(changed, int | float) else 0.0,
    )


def robot_summary(
    robot: str, entries: Sequence[Entry], snapshot: Callable[[str], dict[str, object]]
) -> Summary:
    """``models.AlarmSummary`` of one robot's alarms; ``snapshot(key)`` gives an alarm's
    ``models.Alarm`` (asked for the annunciated ones only)."""
    active = unacknowledged = shelved = suppressed = 0
    by_priority = {p.value: dict.fromkeys(_COUNTED, 0) for p in Priority}
    top: dict[str, object] | None = None
    for definition, status in entries:
        state = status.state
        active += state.active
        unacknowledged += not state.acknowledged
        shelved += status.shelved
        suppressed += state is AlarmState.SUPPRESSED
        if not annunciated(status):
            continue
        counts = by_priority[definition.priority.value]
        counts["annunciated"] += 1
        counts["active"] += state.active
        counts["unacknowledged"] += not state.acknowledged
        alarm = snapshot(definition.key)
        if top is None or urgency(alarm) < urgency(top):
            top = alarm
    return {
        "robot": robot,
        "active": active,
        "unacknowledged": unacknowledged,
        "shelved": shelved,
        "suppressed": suppressed,
        "annunciated": sum(c["annunciated"] for c in by_priority.values()),
        "highest_priority": None if top is None else top["priority"],
        "by_priority": by_priority,
        "top": None if top is None else {name: top[name] for name in BRIEF_KEYS},
    }


def priority_counts(entries: Iterable[Entry]) -> dict[tuple[str, str], int]:
    """``(priority, "active" | "unacknowledged" | "shelved" | "suppressed")`` → alarms."""
    whats = ("active", "unacknowledged", "shelved", "suppressed")
    out = {(p.value, what): 0 for p in Priority for what in whats}
    for definition, status in entries:
        level = definition.priority.value
        state = status.state
        out[(level, "active")] += state.active
        out[(level, "unacknowledged")] += not state.acknowledged
        out[(level, "shelved")] += status.shelved
        out[(level, "suppressed")] += state is AlarmState.SUPPRESSED
    return out


def cell_summary(robots: Sequence[Summary]) -> Summary:
    """``models.CellAlarmSummary``: every robot's summary, in the settings' order, and the
    cell's most urgent annunciated alarm (for a banner line naming its robot)."""
    top: dict[str, object] | None = None
    for summary in robots:
        brief = summary["top"]
        if isinstance(brief, dict) and (top is None or urgency(brief) < urgency(top)):
            top = brief
    annunciated_total = 0
    for summary in robots:
        count = summary["annunciated"]
        annunciated_total += count if isinstance(count, int) else 0
    return {
        "robots": list(robots),
        "annunciated": annunciated_total,
        "highest_priority": None if top is None else top["priority"],
        "top": top,
    }
