"""Layer: service. One robot's alarms: evaluated on every frame, on the connection's changes and
on a slow tick; acknowledged and shelved by operators; announced as ``alarm`` events; persisted.

``observe`` is called for every frame the robot's frame watch takes (``robots.watch``, a consumer of
the robot's frames on the web loop, never on the cyclic thread), in order, before the frames are
sent to clients: an alarm comes with the first frame that shows its condition. A frame that changes
nothing allocates nothing (``conditions``); only a change builds an event and queues its row
(``persistence.AlarmStore.submit``, no wait). The same ``Frame`` object again (the originator hands
it on while the robot's bytes do not change) is not evaluated again unless a condition's delay runs.

The connection's alarms (lost or stale, Forward Open refused) and the packet loss rate are
evaluated by ``tick`` (``TICK_S``) and on each connection state change; shelving expiries too.

An alarm that comes as the consequence of another (``consequences``: SAFE_OFF after an
emergency stop's reset, a refused reconnection after the connection was lost) is suppressed by
design: recorded and announced, not annunciated, nothing to acknowledge.
"""

from __future__ import annotations

import collections
import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Final

from cobot_hmi.codec import Frame
from cobot_hmi.layout import ROBOT_STATES, Direction, field_by_name
from cobot_hmi.service.alarms import definitions as d
from cobot_hmi.service.alarms.conditions import (
    CAME,
    UNCHANGED,
    BitCondition,
    Condition,
    ElementCondition,
    LimitCondition,
    StateCondition,
)
from cobot_hmi.service.alarms.consequences import cause_of
from cobot_hmi.service.alarms.definitions import AlarmDefinition
from cobot_hmi.service.alarms.persistence import AlarmChange
from cobot_hmi.service.alarms.shelving import (
    DEFAULT_MAX_S,
    AlarmRefusedError,
    NotShelvableError,
    ShelvingRules,
)
from cobot_hmi.service.alarms.state import (
    AlarmState,
    AlarmStatus,
    NothingToAcknowledgeError,
    Transition,
)
from cobot_hmi.service.alarms.summary import priority_counts, robot_summary

__all__ = [
    "AlarmEngine",
    "AlarmRefusedError",
    "NotShelvableError",
    "UnknownAlarmError",
    "UserAlarm",
]

log = logging.getLogger(__name__)

TICK_S: Final = 0.5
"""Period of the connection, packet loss and shelving checks."""
GAP_WINDOW_S: Final = 60.0

Event = dict[str, object]
RETURNED_WORDS: Final = "unshelved: the condition cleared while shelved and came again"
"""The comment of an activation that ended a shelving (``AlarmStatus.process``)."""
_STATE_VALUES: Final = {s.name: s.value for s in ROBOT_STATES}


class UnknownAlarmError(LookupError):
    def __init__(self, alarm_id: str, known: list[str]) -> None:
        super().__init__(f"no alarm {alarm_id!r}")
        self.alarm_id = alarm_id
        self.known = known


@dataclass(frozen=True, slots=True)
class UserAlarm:
    """A user-defined alarm as the engine needs it (from an ``[[alarms]]`` table)."""

    name: str
    field: str
    index: int | None
    high: float | None = None
    low: float | None = None
    active_when: bool | None = None
    deadband: float = 0.0
    on_delay_s: float = 0.0
    off_delay_s: float = 0.0
    priority: str = "medium"
    message: str = ""

    @property
    def element(self) -> str:
        return self.field if self.index is None else f"{self.field}.{self.index}"

    @property
    def bit(self) -> bool:
        return field_by_name(Direction.T_TO_O, self.field).value_kind == "bool"


@dataclass(slots=True)
class _Alarm:
    definition: AlarmDefinition
    status: AlarmStatus
    condition: Condition | None


def _builtin_alarms(
    motor_temperature_c: float, motor_temperature_deadband_c: float, gap_rate_per_min: float
) -> list[_Alarm]:
    """The built-in alarms, each with the condition the frames are checked against (none for
    the connection's and the recording's, which other parts raise)."""
    definitions = d.builtin_definitions(
        motor_temperature_c=motor_temperature_c, gap_rate_per_min=gap_rate_per_min
    )
    conditions: dict[str, Condition] = {
        d.EMERGENCY_STOP: StateCondition(
            _STATE_VALUES["EMERGENCY_STOP"], "EMERGENCY_STOP", "emergency_stopped"
        ),
        d.PROTECTIVE_STOP: StateCondition(
            _STATE_VALUES["INTERRUPTED"], "INTERRUPTED", "safety_stopped"
        ),
        d.SAFE_OFF: StateCondition(_STATE_VALUES["SAFE_OFF"], "SAFE_OFF"),
    }
    alarms = []
    for definition in definitions:
        condition = conditions.get(definition.key)
        if condition is None and definition.kind == "limit" and definition.element:
            field, _, index = definition.element.partition(".")
            condition = LimitCondition(
                definition.element,
                field,
                int(index),
                high=definition.high,
                low=None,
                deadband=motor_temperature_deadband_c,
            )
        alarms.append(_Alarm(definition, AlarmStatus(), condition))
    return alarms


def _user_alarm(user: UserAlarm) -> _Alarm:
    """A user's alarm on a bit (its state) or a value (its limits), with its delays."""
    active_when = True if user.active_when is None else user.active_when
    definition = d.user_definition(
        user.name,
        user.element,
        priority=user.priority,
        message=user.message,
        high=user.high,
        low=user.low,
        bit=user.bit,
        active_when=active_when,
    )
    condition: ElementCondition
    if user.bit:
        condition = BitCondition(
            user.element,
            user.field,
            user.index,
            active_when=active_when,
            on_delay_s=user.on_delay_s,
            off_delay_s=user.off_delay_s,
        )
    else:
        condition = LimitCondition(
            user.element,
            user.field,
            user.index,
            high=user.high,
            low=user.low,
            deadband=user.deadband,
            on_delay_s=user.on_delay_s,
            off_delay_s=user.off_delay_s,
        )
    return _Alarm(definition, AlarmStatus(), condition)


class AlarmEngine:
    """The alarms of the robot called ``robot`` (see the module docstring)."""

    def __init__(
        self,
        robot: str,
        *,
        motor_temperature_c: float,
        motor_temperature_deadband_c: float,
        gap_rate_per_min: float,
        connection_delay_s: float,
        shelve_max_s: float,
        shelve_max_by_priority_s: Mapping[str, float] | None = None,
        consequence_window_s: float = 5.0,
        user_alarms: tuple[UserAlarm, ...] = (),
        publish: Callable[[Event], None] | None = None,
        persist: Callable[[AlarmChange], None] | None = None,
        tags: Callable[[], Mapping[str, str]] | None = None,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.robot = robot
        self.gap_rate_per_min = gap_rate_per_min
        self.connection_delay_s = connection_delay_s
        longest = (
            DEFAULT_MAX_S
            if shelve_max_by_priority_s is None
            # A priority the settings leave out keeps its default (advisory has no setting).
            else DEFAULT_MAX_S | {d.Priority(p): s for p, s in shelve_max_by_priority_s.items()}
        )
        self.shelving = ShelvingRules(shelve_max_s, longest)
        """Which alarms may be shelved, and for how long (``shelving``)."""
        self.consequence_window_s = consequence_window_s
        """An alarm coming this long after its cause cleared is still its consequence, s."""
        self.publish = publish
        self.persist = persist
        self._tags = tags
        self._clock = clock
        self.alarms: dict[str, _Alarm] = {}
        alarms = _builtin_alarms(
            motor_temperature_c, motor_temperature_deadband_c, gap_rate_per_min
        )
        alarms += [_user_alarm(user) for user in user_alarms]
        self.alarms = {alarm.definition.key: alarm for alarm in alarms}
        frame_checks = [(a, a.condition) for a in alarms if a.condition is not None]
        self._frame_checks: tuple[tuple[_Alarm, Condition], ...] = tuple(frame_checks)
        self._frame_conditions: tuple[Condition, ...] = tuple(c for _, c in frame_checks)
        self._failed = False
        self._settled_on: Frame | None = None
        """The frame last evaluated, when no condition's delay ran after it: the originator
        hands on the same ``Frame`` while the robot's bytes do not change (its monitoring
        values refresh every 100 ms), and that frame again cannot change any condition."""
        # Connection health.
        self._bad_since: float | None = None
        self._gap_samples: collections.deque[tuple[float, int]] = collections.deque()
        self.gaps_per_min: float | None = None
        """T→O sequence gaps in the last minute (``None`` until a minute's samples exist
        or while not connected)."""

    @property
    def gaps_total(self) -> int | None:
        """T→O sequence gaps of the current connection at the last tick (``None``: not
        connected)."""
        samples = self._gap_samples
        return samples[-1][1] if samples else None

    # ------------------------------------------------------------ identity

    def alarm_id(self, key: str) -> str:
        return f"{self.robot}:{key}"

    @property
    def failed(self) -> bool:
        """Frame evaluation stopped after an error (logged; ``/metrics`` shows it)."""
        return self._failed

    @property
    def packet_loss_high(self) -> bool:
        """Packet loss above the threshold (the status' amber connection badge)."""
        return self.alarms[d.PACKET_LOSS].status.state.active

    # ------------------------------------------------------------ restart

    def restore(self, records: Mapping[str, dict[str, object]]) -> None:
        """Take the persisted records (a restart): states, acknowledgements, shelving. The
        conditions start from the persisted activity, so the first frame says only what
        changed while the service was down."""
        for key, record in records.items():
            alarm = self.alarms.get(key)
            if alarm is None:
                continue  # an alarm the settings no longer define
            alarm.status = AlarmStatus.from_json(record)
            if alarm.condition is not None:
                alarm.condition.restore(alarm.status.state.active)
        self._settled_on = None

    # ------------------------------------------------------------ frames (hot path)

    def observe(self, frame: Frame, time_s: float) -> list[Event] | None:
        """Every frame, in order: the events of the alarms it changes, or ``None``."""
        if self._failed or frame is self._settled_on:
            return None
        events: list[Event] | None = None
        conditions = self._frame_conditions
        count = len(conditions)
        index = 0
        try:
            # An index, not ``for … in``: a for loop allocates an iterator on every frame.
            while index < count:
                change = conditions[index].update(frame, time_s)
                index += 1
                if change == UNCHANGED:
                    continue
                alarm, condition = self._frame_checks[index - 1]
                value, message = condition.describe(frame, self._tag_names())
                event = self._process(alarm, change == CAME, time_s, value, message)
                if event is not None:
                    if events is None:
                        events = []
                    events.append(event)
            index = 0  # any delay running? (a loop again: a generator would allocate)
            while index < count and not conditions[index].delaying:
                index += 1
            self._settled_on = frame if index == count else None
        except Exception:  # a bug here must not stop the frames: this robot's alarms stop
            self._failed = True
            log.exception("%s: alarm evaluation failed; frame alarms are off", self.robot)
        return events

    # ------------------------------------------------------------ connection (slow)

    def connection(
        self,
        *,
        connected: bool,
        refused: bool,
        reason: str | None,
        frame_age_s: float | None,
        stale_after_s: float,
        now_s: float,
        monotonic_s: float,
    ) -> list[Event]:
        """The connection's alarms from its state now (a change, or the tick)."""
        events: list[Event] = []
        refused_alarm = self.alarms[d.FORWARD_OPEN_REFUSED]
        was_refused = refused_alarm.status.state.active
        # Comes with a refusal, goes once a connection is made (not while still trying).
        if refused != was_refused and (refused or connected):
            message = f"Forward Open refused: {reason}" if refused else "connected"
            event = self._process(refused_alarm, refused, now_s, None, message)
            if event is not None:
                events.append(event)
        stale = frame_age_s is None or frame_age_s > stale_after_s
        bad = not connected or stale
        lost = self.alarms[d.CONNECTION_LOST]
        active = lost.status.state.active
        if not bad:
            self._bad_since = None
            if active:
                event = self._process(lost, False, now_s, None, "connected, frames arriving")
                if event is not None:
                    events.append(event)
        else:
            if self._bad_since is None:
                self._bad_since = monotonic_s
            if not active and monotonic_s - self._bad_since >= self.connection_delay_s:
                if connected:
                    what = f"no frame for {frame_age_s:.1f} s" if frame_age_s else "no frame"
                else:
                    what = f"not connected{': ' + reason if reason else ''}"
                event = self._process(lost, True, now_s, frame_age_s, what)
                if event is not None:
                    events.append(event)
        return events

    def gaps(self, gaps_total: int | None, *, now_s: float, monotonic_s: float) -> list[Event]:
        """The T→O gap counter now (``None``: not connected): the packet loss alarm."""
        samples = self._gap_samples
        if gaps_total is None:
            samples.clear()
            self.gaps_per_min = None
            return []
        if samples and gaps_total < samples[-1][1]:
            samples.clear()  # a new connection counts from zero
        samples.append((monotonic_s, gaps_total))
        while len(samples) > 1 and monotonic_s - samples[1][0] >= GAP_WINDOW_S:
            samples.popleft()
        oldest_t, oldest_gaps = samples[0]
        self.gaps_per_min = float(gaps_total - oldest_gaps)
        alarm = self.alarms[d.PACKET_LOSS]
        active = self.gaps_per_min > self.gap_rate_per_min
        if active == alarm.status.state.active:
            return []
        span_s = min(GAP_WINDOW_S, monotonic_s - oldest_t)
        words = f"{self.gaps_per_min:g} gaps in the last {span_s:.0f} s"
        event = self._process(alarm, active, now_s, self.gaps_per_min, words)
        return [] if event is None else [event]

    def raised(
        self, key: str, *, active: bool, message: str, now_s: float, value: float | None = None
    ) -> list[Event]:
        """An alarm another part raises and clears: ``recording_paused`` (the history recorder
        paused, ``message`` says why, or resumed), ``health.N`` (robot health's advice on a
        joint, ``service.health``: active while its verdict is watch or act, ``message`` its
        reason, kept up to date while active)."""
        alarm = self.alarms[key]
        if active == alarm.status.state.active:
            if active:
                alarm.status.message = message
                alarm.status.value = value
            return []
        event = self._process(alarm, active, now_s, value, message)
        return [] if event is None else [event]

    def expire_shelving(self, now_s: float) -> list[Event]:
        events = []
        for alarm in self.alarms.values():
            transition = alarm.status.expire(now_s)
            if transition is not None:
                events.append(self._changed(alarm, transition, now_s))
        return events

    # ------------------------------------------------------------ operators

    def find(self, alarm_id: str) -> _Alarm:
        robot, _, key = alarm_id.partition(":")
        alarm = self.alarms.get(key) if robot == self.robot else None
        if alarm is None:
            raise UnknownAlarmError(alarm_id, [self.alarm_id(k) for k in self.alarms])
        return alarm

    def acknowledge(self, alarm_id: str, user: str, comment: str | None) -> tuple[Event, bool]:
        """Acknowledge: (the alarm's snapshot, whether it changed). ``AlarmRefusedError`` for a
        normal alarm (nothing to acknowledge)."""
        alarm = self.find(alarm_id)
        now_s = self._clock()
        try:
            transition = alarm.status.acknowledge(user, comment, now_s)
        except NothingToAcknowledgeError:
            raise AlarmRefusedError(f"{alarm_id} is normal: nothing to acknowledge") from None
        if transition is None:
            return self.snapshot(alarm), False
        self._emit(self._changed(alarm, transition, now_s, user=user, comment=comment))
        return self.snapshot(alarm), True

    def shelve(self, alarm_id: str, user: str, reason: str, duration_s: float) -> Event:
        alarm = self.find(alarm_id)
        self.shelving.check(alarm.definition, duration_s)
        if not reason.strip():
            raise AlarmRefusedError("shelving needs a reason")
        now_s = self._clock()
        transition = alarm.status.shelve(user, reason.strip(), now_s + duration_s, now_s)
        self._emit(self._changed(alarm, transition, now_s, user=user, comment=reason.strip()))
        return self.snapshot(alarm)

    def unshelve(self, alarm_id: str, user: str) -> tuple[Event, bool]:
        alarm = self.find(alarm_id)
        now_s = self._clock()
        transition = alarm.status.unshelve(now_s)
        if transition is None:
            return self.snapshot(alarm), False
        self._emit(self._changed(alarm, transition, now_s, user=user))
        return self.snapshot(alarm), True

    # ------------------------------------------------------------ answers

    def snapshot(self, alarm: _Alarm) -> Event:
        """``models.Alarm`` of one alarm as JSON-ready data."""
        definition, status = alarm.definition, alarm.status
        element = definition.element
        tag = self._tag_names().get(element) if element is not None else None
        cause = self.alarms.get(status.suppressed_by) if status.suppressed_by else None
        return {
            "id": self.alarm_id(definition.key),
            "robot": self.robot,
            "key": definition.key,
            "name": definition.name,
            "description": definition.description,
            "priority": definition.priority.value,
            "priority_rank": definition.priority.rank,
            "colour": definition.colour,
            "kind": definition.kind,
            "element": element,
            "label": definition.label,
            "tag": tag,
            "unit": definition.unit,
            "high": definition.high,
            "low": definition.low,
            "active": status.state.active,
            "acknowledged": status.state.acknowledged,
            "shelved": status.shelved,
            "shelve_max_s": self.shelving.max_s(definition),
            "shelve_refusal": self.shelving.refusal(definition),
            **status.to_json(),
            "suppressed_by": None if cause is None else self.alarm_id(cause.definition.key),
            "suppressed_by_name": None if cause is None else cause.definition.name,
        }

    def snapshot_of(self, key: str) -> Event:
        return self.snapshot(self.alarms[key])

    def current(self) -> list[Event]:
        """Alarms that are not normal (active, or unacknowledged), most urgent first."""
        chosen = [a for a in self.alarms.values() if a.status.state.value != "normal"]
        chosen.sort(key=lambda a: (a.definition.priority.rank, -(a.status.changed_at or 0.0)))
        return [self.snapshot(a) for a in chosen]

    def all(self) -> list[Event]:
        return [self.snapshot(a) for a in self.alarms.values()]

    def summary(self) -> dict[str, object]:
        """``models.AlarmSummary`` of this robot (``summary.robot_summary``)."""
        entries = [(a.definition, a.status) for a in self.alarms.values()]
        return robot_summary(self.robot, entries, self.snapshot_of)

    def counts(self) -> dict[tuple[str, str], int]:
        """``(priority, "active" | "unacknowledged" | "shelved" | "suppressed")`` → alarms
        (``/metrics``)."""
        return priority_counts((a.definition, a.status) for a in self.alarms.values())

    # ------------------------------------------------------------ inside

    def _tag_names(self) -> Mapping[str, str]:
        return self._tags() if self._tags is not None else {}

    def _process(
        self,
        alarm: _Alarm,
        active: bool,
        time_s: float,
        value: float | bool | None,
        message: str,
    ) -> Event | None:
        cause = None
        if active and not alarm.status.state.active:
            statuses = {key: other.status for key, other in self.alarms.items()}
            cause = cause_of(alarm.definition.key, statuses, time_s, self.consequence_window_s)
        was_shelved = alarm.status.shelved
        transition = alarm.status.process(active, time_s, suppressed_by=cause)
        alarm.status.value = value
        alarm.status.message = message
        if transition is None:
            return None
        if was_shelved and not alarm.status.shelved:  # it cleared while shelved and came again
            return self._changed(alarm, transition, time_s, comment=RETURNED_WORDS)
        return self._changed(alarm, transition, time_s)

    def _changed(
        self,
        alarm: _Alarm,
        transition: Transition,
        time_s: float,
        *,
        user: str | None = None,
        comment: str | None = None,
    ) -> Event:
        """Persist the change; the ``alarm`` event that announces it."""
        snapshot = self.snapshot(alarm)
        if self.persist is not None:
            status = alarm.status
            self.persist(
                AlarmChange(
                    time=time_s,
                    robot=self.robot,
                    alarm_id=str(snapshot["id"]),
                    key=alarm.definition.key,
                    name=alarm.definition.name,
                    priority=alarm.definition.priority.value,
                    transition=transition.value,
                    state=status.state.value,
                    shelved=status.shelved,
                    message=status.message,
                    value=status.value,
                    label=alarm.definition.label,
                    tag=snapshot["tag"] if isinstance(snapshot["tag"], str) else None,
                    user=user,
                    comment=comment,
                    record=status.to_json(),
                    suppressed_by=(
                        snapshot["suppressed_by"]
                        if status.state is AlarmState.SUPPRESSED
                        and isinstance(snapshot["suppressed_by"], str)
                        else None
                    ),
                )
            )
        return {
            "kind": "alarm",
            "time": time_s,
            "robot": self.robot,
            "transition": transition.value,
            "user": user,
            "comment": comment,
            "alarm": snapshot,
        }

    def _emit(self, event: Event) -> None:
        if self.publish is not None:
            self.publish(event)
