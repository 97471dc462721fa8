"""Layer: service (Sparkplug). Pure: a robot's metrics that come from the service's events, not
from its frames: its alarms, its cycle times and its joints' health (docs/operations.md
"Sparkplug B", docs/api.md "The plant").

- ``Alarm/<key>/Active`` (Boolean), ``Alarm/<key>/Priority`` and ``Alarm/<key>/Text`` (String)
  for every alarm the robot's alarm engine defines, all declared in the DBIRTH (an alarm that
  comes later needs no rebirth: its metrics are already there). ``Active`` is the condition
  (ISA-18.2's active states, a suppressed-by-design alarm included), stamped with the time the
  alarm engine saw it change; ``Text`` is the alarm's name in words.
- ``Cycle/Last`` and ``Cycle/Average`` (Double, s): the newest uninterrupted cycle and the mean
  of the newest ``CYCLE_AVERAGE_OF`` of them (the cell's own cycles API's default window).
- ``Health/Verdict`` (the robot's: its worst joint's), and per joint ``Health/J<n>/Verdict``
  (ok, watch, act), ``Health/J<n>/Reason`` (String) and ``Health/J<n>/Life Used`` (Double, % of
  the rated reducer life), from the service's ``health`` events; Null until the first.

Every value is reported by exception: a change returns ``(offset, value, time ms)`` and nothing
else does (``Life Used`` by its deadband). Each alarm's transitions are also kept (bounded) so
that the edge node can send a host the ones it asks for again (``transitions_since``).

Imports only ``catalogue`` and ``payload``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Final

from cobot_hmi.sparkplug.catalogue import MetricDef, Role
from cobot_hmi.sparkplug.payload import DataType, MetricValue

ALARM_PREFIX: Final = "Alarm/"
CYCLE_LAST: Final = "Cycle/Last"
CYCLE_AVERAGE: Final = "Cycle/Average"
HEALTH_PREFIX: Final = "Health/"
CYCLE_AVERAGE_OF: Final = 20
LIFE_USED_DEADBAND: Final = 0.01
"""Life used moves by hundredths of a percent a day at most: reported when it moved this much."""
HISTORY_TRANSITIONS: Final = 2048
"""Alarm transitions a robot keeps to send again (a host that asks for more gets these)."""
JOINTS: Final = 6

EventChange = tuple[int, MetricValue | None, int]
"""``(metric offset, value or None for Null, timestamp ms)``."""


@dataclass(frozen=True, slots=True)
class AlarmDeclaration:
    """One alarm of the robot as its DBIRTH declares it."""

    key: str
    text: str
    priority: str
    active: bool
    changed_ms: int | None


def alarm_declarations(snapshots: Iterable[Mapping[str, object]]) -> list[AlarmDeclaration]:
    """From the alarm engine's snapshots (``AlarmEngine.all``)."""
    found = []
    for snapshot in snapshots:
        active = snapshot.get("active") is True
        # Its Active's time: when it came or went (an acknowledgement changes neither).
        changed = snapshot.get("activated_at" if active else "cleared_at")
        if not isinstance(changed, int | float):
            changed = snapshot.get("changed_at")
        found.append(
            AlarmDeclaration(
                key=str(snapshot.get("key")),
                text=str(snapshot.get("name") or snapshot.get("key")),
                priority=str(snapshot.get("priority") or "medium"),
                active=active,
                changed_ms=int(changed * 1000) if isinstance(changed, int | float) else None,
            )
        )
    return found


def metric_key(key: str) -> str:
    """An alarm key as a metric name's part (``/`` is Sparkplug's folder separator)."""
    return key.replace("/", "_")


def _number(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


class EventMetrics:
    """One robot's event metrics from offset ``first_offset`` on (see the module docstring)."""

    def __init__(
        self,
        first_offset: int,
        alarms: Sequence[AlarmDeclaration],
        now_ms: int,
        joints: int = JOINTS,
    ) -> None:
        self.metrics: list[MetricDef] = []
        self.values: list[MetricValue | None] = []
        self.stamps: list[int] = []
        self._first = first_offset
        self.alarm_offsets: dict[str, int] = {}
        """Alarm key → the offset of its ``Active`` (``Priority`` and ``Text`` follow)."""
        for alarm in alarms:
            name = f"{ALARM_PREFIX}{metric_key(alarm.key)}"
            stamp = alarm.changed_ms if alarm.changed_ms is not None else now_ms
            self.alarm_offsets[alarm.key] = self._add(
                f"{name}/Active", DataType.BOOLEAN, alarm.active, stamp, description="active"
            )
            self._add(f"{name}/Priority", DataType.STRING, alarm.priority, now_ms, description="")
            self._add(f"{name}/Text", DataType.STRING, alarm.text, now_ms, description="in words")
        seconds = {"description": "an uninterrupted cycle's duration", "unit": "s"}
        self.cycle_last = self._add(CYCLE_LAST, DataType.DOUBLE, None, now_ms, **seconds)
        self.cycle_average = self._add(CYCLE_AVERAGE, DataType.DOUBLE, None, now_ms, **seconds)
        self.health_verdict = self._add(
            f"{HEALTH_PREFIX}Verdict", DataType.STRING, None, now_ms, description="worst joint's"
        )
        self.health_offsets: dict[int, int] = {}
        """Joint (1-based) → the offset of its ``Verdict`` (``Reason``, ``Life Used`` follow)."""
        for joint in range(1, joints + 1):
            name = f"{HEALTH_PREFIX}J{joint}"
            self.health_offsets[joint] = self._add(
                f"{name}/Verdict", DataType.STRING, None, now_ms, description="ok, watch or act"
            )
            self._add(f"{name}/Reason", DataType.STRING, None, now_ms, description="")
            self._add(
                f"{name}/Life Used",
                DataType.DOUBLE,
                None,
                now_ms,
                description="the reducer's rated life used",
                unit="%",
            )
        self._cycles: deque[float] = deque(maxlen=CYCLE_AVERAGE_OF)
        self.history: deque[EventChange] = deque(maxlen=HISTORY_TRANSITIONS)
        """Every ``Active`` change, oldest first (``transitions_since``)."""

    def _add(
        self,
        name: str,
        datatype: DataType,
        value: MetricValue | None,
        stamp_ms: int,
        *,
        description: str,
        unit: str = "",
    ) -> int:
        offset = self._first + len(self.metrics)
        self.metrics.append(
            MetricDef(
                name=name,
                offset=offset,
                datatype=datatype,
                role=Role.EVENT,
                unit=unit,
                description=description,
            )
        )
        self.values.append(value)
        self.stamps.append(stamp_ms)
        return offset

    def restore(self, alarms: Iterable[AlarmDeclaration]) -> None:
        """The alarms' state as the alarm engine restored it (no change reported: the next
        birth carries it)."""
        for alarm in alarms:
            offset = self.alarm_offsets.get(alarm.key)
            if offset is None:
                continue
            index = offset - self._first
            self.values[index : index + 3] = [alarm.active, alarm.priority, alarm.text]
            if alarm.changed_ms is not None:
                self.stamps[index] = alarm.changed_ms

    def metric(self, offset: int) -> MetricDef:
        return self.metrics[offset - self._first]

    def _set(self, offset: int, value: MetricValue | None, time_ms: int) -> list[EventChange]:
        index = offset - self._first
        if self.values[index] == value:
            return []
        self.values[index] = value
        self.stamps[index] = time_ms
        return [(offset, value, time_ms)]

    # ------------------------------------------------------------ events

    def on_event(self, event: Mapping[str, object]) -> list[EventChange]:
        """What one event of the robot changes (``alarm``, ``cycle``, ``health``)."""
        kind = event.get("kind")
        time_s = _number(event.get("time"))
        time_ms = int(time_s * 1000) if time_s is not None else 0
        if kind == "alarm":
            return self._alarm(event.get("alarm"), time_ms)
        if kind == "cycle":
            return self._cycle(event, time_ms)
        if kind == "health":
            return self._health(event, time_ms)
        return []

    def _alarm(self, snapshot: object, time_ms: int) -> list[EventChange]:
        if not isinstance(snapshot, Mapping):
            return []
        offset = self.alarm_offsets.get(str(snapshot.get("key")))
        if offset is None:
            return []  # an alarm the DBIRTH did not declare: none (the engine's set is fixed)
        changes = self._set(offset, snapshot.get("active") is True, time_ms)
        self.history.extend(changes)
        changes += self._set(offset + 1, str(snapshot.get("priority") or "medium"), time_ms)
        changes += self._set(offset + 2, str(snapshot.get("name") or snapshot.get("key")), time_ms)
        return changes

    def _cycle(self, event: Mapping[str, object], time_ms: int) -> list[EventChange]:
        duration_s = _number(event.get("duration_s"))
        if duration_s is None or event.get("interruption"):
            return []  # an interrupted cycle is no measure of the program (as the cycles API)
        end_s = _number(event.get("end"))
        stamp = int(end_s * 1000) if end_s is not None else time_ms
        self._cycles.append(duration_s)
        average = round(sum(self._cycles) / len(self._cycles), 6)
        # Each cycle is a value of Cycle/Last, even one as long as the one before: the plant
        # counts them.
        index = self.cycle_last - self._first
        self.values[index] = duration_s
        self.stamps[index] = stamp
        average_changes = self._set(self.cycle_average, average, stamp)
        return [(self.cycle_last, duration_s, stamp), *average_changes]

    def _health(self, event: Mapping[str, object], time_ms: int) -> list[EventChange]:
        joints = event.get("joints")
        if not isinstance(joints, Sequence):
            return []
        changes: list[EventChange] = []
        verdict = event.get("verdict")
        if isinstance(verdict, str):
            changes += self._set(self.health_verdict, verdict, time_ms)
        for entry in joints:
            if not isinstance(entry, Mapping):
                continue
            joint = entry.get("joint")
            offset = self.health_offsets.get(joint) if isinstance(joint, int) else None
            if offset is None:
                continue
            verdict, reason = entry.get("verdict"), entry.get("reason")
            if isinstance(verdict, str):
                changes += self._set(offset, verdict, time_ms)
            if isinstance(reason, str):
                changes += self._set(offset + 1, reason, time_ms)
            life = _number(entry.get("life_used_percent"))
            if life is not None:
                before = self.values[offset + 2 - self._first]
                moved = not isinstance(before, float) or abs(life - before) >= LIFE_USED_DEADBAND
                if moved:
                    changes += self._set(offset + 2, life, time_ms)
        return changes

    # ------------------------------------------------------------ history

    def transitions_since(self, since_ms: int) -> list[EventChange]:
        """The alarms' transitions from ``since_ms`` on, oldest first."""
        return [change for change in self.history if change[2] >= since_ms]
