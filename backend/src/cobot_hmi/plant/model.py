"""Layer: plant (a door above the service). Pure: what the plant knows of every edge node and
device it heard (their metrics' last live values, online or offline since when) and every alarm
transition, in time order, with the figures an alarm list needs (ISA-18.2: alarms per 10
minutes, floods, bad actors).

A device's state in words is its ``robot_state`` metric (our cells: the layout's code, named
here from ``layout.py``; another edge node may publish the words as a string). Its alarms are
the metrics ``Alarm/<id>/Active`` (Boolean), ``Alarm/<id>/Priority`` (String: critical, high,
medium, low, advisory) and ``Alarm/<id>/Text`` (String); its cycle times ``Cycle/Last`` and
``Cycle/Average`` (seconds); its health ``Health/<name>`` (our cells: ``Health/Verdict``, and per
joint ``Health/J<n>/Verdict``, ``…/Reason``, ``…/Life Used`` in %), each in words.
docs/api.md "The plant".

Imports only ``layout`` of the project.
"""

from __future__ import annotations

import bisect
from collections import Counter, deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final

from cobot_hmi.layout import ROBOT_STATES, robot_state_name

MetricValue = bool | int | float | str

ALARM_PREFIX: Final = "Alarm/"
STATE_METRIC: Final = "robot_state"
HMI_URL_METRIC: Final = "Node Info/HMI URL"
AREA_METRIC: Final = "Node Info/Area"
CYCLE_LAST: Final = "Cycle/Last"
CYCLE_AVERAGE: Final = "Cycle/Average"
HEALTH_PREFIX: Final = "Health/"
PRIORITIES: Final = ("critical", "high", "medium", "low", "advisory")
"""Most urgent first; advisory: a cell's maintenance advice (robot health), below them all."""
FLOOD_WINDOW_MS: Final = 10 * 60 * 1000
FLOOD_ALARMS: Final = 10
"""ISA-18.2: more than 10 alarms in 10 minutes is a flood."""
ALARM_LOG_LIMIT: Final = 100_000
"""Transitions kept in memory (the history keeps every one on disk)."""

_STATE_INFO: Final = {state.name: state for state in ROBOT_STATES}


def state_group(state_name: str | None) -> str | None:
    """running, standby, stopped or error: the plant's reading of a robot state (red on the
    pendant is an error; a running or measuring state runs; a standby state stands by)."""
    if state_name is None:
        return None
    info = _STATE_INFO.get(state_name)
    if "RUNNING" in state_name or state_name == "AUTO_MEASURE":
        return "running"
    if "STANDBY" in state_name:
        return "standby"
    if info is not None and "red" in info.pendant_colours:
        return "error"
    return "stopped"


@dataclass(slots=True)
class MetricState:
    """A metric's last live value (historical values go to the history only)."""

    value: MetricValue | None
    timestamp_ms: int


@dataclass(frozen=True, slots=True)
class ActiveAlarm:
    alarm: str
    priority: str
    text: str
    since_ms: int


@dataclass(frozen=True, slots=True)
class AlarmTransition:
    """An alarm coming (``active``) or going, at the time the cell says it happened."""

    time_ms: int
    group: str
    node: str
    device: str
    alarm: str
    active: bool
    priority: str
    text: str
    historical: bool


@dataclass(slots=True)
class DeviceView:
    name: str
    online: bool = False
    since_ms: int = 0
    metrics: dict[str, MetricState] = field(default_factory=dict)
    alarm_since_ms: dict[str, int] = field(default_factory=dict)
    """Each active alarm's start (live or replayed)."""
    _actives: list[str] = field(default_factory=list, init=False, repr=False, compare=False)
    _health: list[str] = field(default_factory=list, init=False, repr=False, compare=False)
    _listed: int = field(default=-1, init=False, repr=False, compare=False)
    """How many metrics there were when ``_actives`` and ``_health`` were listed: a device's
    metrics are only ever added to (a value changes in place), so the lists stay right until
    one more comes, and the page, which asks for every device several times a second, does not
    look through every metric of each."""

    def _names(self) -> tuple[list[str], list[str]]:
        """The names of the alarms' ``Active`` metrics and of the health metrics."""
        if self._listed != len(self.metrics):
            names = list(self.metrics)
            self._actives = [
                n for n in names if n.startswith(ALARM_PREFIX) and n.endswith("/Active")
            ]
            self._health = [n for n in names if n.startswith(HEALTH_PREFIX)]
            self._listed = len(names)
        return self._actives, self._health

    def value(self, name: str) -> MetricValue | None:
        metric = self.metrics.get(name)
        return None if metric is None else metric.value

    def state(self) -> str | None:
        """The robot's state in words (the layout's name of its code)."""
        value = self.value(STATE_METRIC)
        if isinstance(value, str):
            return value
        if isinstance(value, int) and not isinstance(value, bool):
            return robot_state_name(value)
        return None

    def alarms_active(self) -> list[ActiveAlarm]:
        """The active alarms, the most urgent first, then the oldest."""
        active = []
        for name in self._names()[0]:
            metric = self.metrics[name]
            if metric.value is not True:
                continue
            alarm = name[len(ALARM_PREFIX) : -len("/Active")]
            active.append(
                ActiveAlarm(
                    alarm,
                    self.alarm_priority(alarm),
                    self.alarm_text(alarm),
                    self.alarm_since_ms.get(alarm, metric.timestamp_ms),
                )
            )
        return sorted(active, key=lambda a: (priority_rank(a.priority), a.since_ms))

    def alarm_priority(self, alarm: str) -> str:
        value = self.value(f"{ALARM_PREFIX}{alarm}/Priority")
        return str(value) if value is not None else "medium"

    def alarm_text(self, alarm: str) -> str:
        value = self.value(f"{ALARM_PREFIX}{alarm}/Text")
        return str(value) if value is not None else alarm

    def health(self) -> dict[str, str]:
        metrics = self.metrics
        return {
            name[len(HEALTH_PREFIX) :]: str(metrics[name].value)
            for name in self._names()[1]
            if metrics[name].value is not None
        }


def priority_rank(priority: str) -> int:
    return PRIORITIES.index(priority) if priority in PRIORITIES else len(PRIORITIES)


@dataclass(slots=True)
class NodeView:
    group: str
    node: str
    online: bool = False
    since_ms: int = 0
    bd_seq: int | None = None
    metrics: dict[str, MetricState] = field(default_factory=dict)
    devices: dict[str, DeviceView] = field(default_factory=dict)

    def text(self, name: str) -> str | None:
        metric = self.metrics.get(name)
        return None if metric is None or metric.value is None else str(metric.value)


class AlarmLog:
    """Every alarm transition heard, in the time order of the cells' own timestamps (a replayed
    one goes where it happened, not at the end), each once, bounded."""

    def __init__(self, limit: int = ALARM_LOG_LIMIT) -> None:
        self._times: deque[int] = deque()
        self._entries: deque[AlarmTransition] = deque()
        self._keys: set[tuple[int, str, str, str, str, bool]] = set()
        """Every kept transition's identity: a cell sends one again when asked (a rebirth after
        lost messages), and it is kept once."""
        self._limit = limit

    @staticmethod
    def _key(t: AlarmTransition) -> tuple[int, str, str, str, str, bool]:
        return (t.time_ms, t.group, t.node, t.device, t.alarm, t.active)

    def add(self, transition: AlarmTransition) -> bool:
        """Keep ``transition`` in time order; ``False`` (not kept) when it is one already kept:
        the same alarm of the same device changing the same way at the same time."""
        key = self._key(transition)
        if key in self._keys:
            return False
        self._keys.add(key)
        index = bisect.bisect_right(self._times, transition.time_ms)
        self._times.insert(index, transition.time_ms)
        self._entries.insert(index, transition)
        while len(self._entries) > self._limit:
            self._times.popleft()
            self._keys.discard(self._key(self._entries.popleft()))
        return True

    def between(self, start_ms: int, end_ms: int) -> list[AlarmTransition]:
        first = bisect.bisect_left(self._times, start_ms)
        last = bisect.bisect_right(self._times, end_ms)
        return [self._entries[i] for i in range(first, last)]

    def __len__(self) -> int:
        return len(self._entries)


@dataclass(frozen=True, slots=True)
class CellAlarmFigures:
    """ISA-18.2 figures of one edge node (a cell) over a window."""

    group: str
    node: str
    alarms_per_10_min: float
    flood: bool
    peak_per_10_min: int
    bad_actors: list[tuple[str, str, int]]
    """(device, alarm, activations), the ten most frequent."""


def alarm_figures(
    transitions: list[AlarmTransition], start_ms: int, end_ms: int
) -> list[CellAlarmFigures]:
    """Per cell: activations per 10 minutes over the window, whether any 10 minutes of it held
    more than ``FLOOD_ALARMS`` (a flood), and its top ten bad actors."""
    by_cell: dict[tuple[str, str], list[AlarmTransition]] = {}
    for t in transitions:
        if t.active:
            by_cell.setdefault((t.group, t.node), []).append(t)
    span_ms = max(end_ms - start_ms, 1)
    figures = []
    for (group, node), activations in sorted(by_cell.items()):
        times = sorted(t.time_ms for t in activations)
        peak = 0
        first = 0
        for last, time_ms in enumerate(times):  # the busiest 10 minutes, a sliding window
            while time_ms - times[first] >= FLOOD_WINDOW_MS:
                first += 1
            peak = max(peak, last - first + 1)
        actors = Counter((t.device, t.alarm) for t in activations)
        figures.append(
            CellAlarmFigures(
                group,
                node,
                len(times) * FLOOD_WINDOW_MS / span_ms,
                peak > FLOOD_ALARMS,
                peak,
                [(d, a, n) for (d, a), n in actors.most_common(10)],
            )
        )
    return figures


STATE_GROUPS: Final = ("running", "standby", "stopped", "error")


@dataclass(frozen=True, slots=True)
class ShiftFigures:
    """One robot over a shift: seconds in each state group (and with no state known), cycles
    counted (each ``Cycle/Last`` value received) and their mean."""

    seconds: dict[str, float]
    cycles: int
    mean_cycle_s: float | None


def shift_figures(
    states: Sequence[tuple[int, str | None]],
    cycle_times_s: Sequence[float],
    start_ms: int,
    end_ms: int,
) -> ShiftFigures:
    """``states``: (time, state name) in time order, the last one before the shift included
    (it says what the shift started in); a state holds until the next, the last until
    ``end_ms``. Time before the first known state is ``unknown``."""
    seconds = dict.fromkeys((*STATE_GROUPS, "unknown"), 0.0)
    current: str | None = None
    since_ms = start_ms
    for time_ms, name in states:
        if time_ms > start_ms:
            stop_ms = min(time_ms, end_ms)
            if stop_ms > since_ms:
                seconds[state_group(current) or "unknown"] += (stop_ms - since_ms) / 1000
            since_ms = max(since_ms, stop_ms)
        current = name
        if time_ms >= end_ms:
            break
    if end_ms > since_ms:
        seconds[state_group(current) or "unknown"] += (end_ms - since_ms) / 1000
    mean = sum(cycle_times_s) / len(cycle_times_s) if cycle_times_s else None
    return ShiftFigures(seconds, len(cycle_times_s), mean)
