"""Layer: plant (a door above the service). Pure: the Sparkplug 3.0 host application's rules,
fed the messages it receives, answering what to publish and what to record; no I/O, no clock
of its own (each message comes with the time it was received).

By the specification ("Host Applications", "Sparkplug Session Management"): an NBIRTH starts a
node's session (its ``bdSeq``, its metrics' names and aliases, ``seq`` 0); every later message
of the node carries the next ``seq`` (modulo 256); a gap, a metric by an alias the births did
not name, or data from a node or device not born is answered with a rebirth request (NCMD
``Node Control/Rebirth`` = true), at most one per node per ``rebirth_interval_s``. An NDEATH
ends the session only when its ``bdSeq`` is the NBIRTH's (a late will of an older connection
is ignored); NDEATH and DDEATH mark the node or device offline since then, its last values
kept. A metric marked ``is_historical`` (a cell's store-and-forward after an outage) is
recorded where it belongs in time, never taken as the live value.

No alarm transition is lost to a lost message: a rebirth request after a gap (and one to every
node the host knew after its own connection was lost: ``on_reconnect``) carries ``Node
Control/Alarm History Since``, the time of the node's last message received in order less
``HISTORY_MARGIN_MS``; our edge node answers with the births and then every alarm transition
since, as historical, which the alarm log keeps once each (``AlarmLog``).

Imports ``sparkplug.payload`` and ``sparkplug.topics`` (the wire) and the plant's model.
"""

from __future__ import annotations

import json
import threading
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final, NamedTuple

from cobot_hmi.plant.model import (
    ALARM_PREFIX,
    AlarmLog,
    AlarmTransition,
    DeviceView,
    MetricState,
    MetricValue,
    NodeView,
)
from cobot_hmi.sparkplug.payload import (
    DataType,
    Payload,
    PayloadError,
    add_metric,
    make_payload,
    parse_payload,
)
from cobot_hmi.sparkplug.topics import NAMESPACE, MessageType

SEQ_MODULO: Final = 256
ACTIVE: Final = "/Active"
BD_SEQ: Final = "bdSeq"
REBIRTH: Final = "Node Control/Rebirth"
ALARM_HISTORY_SINCE: Final = "Node Control/Alarm History Since"
REBIRTH_INTERVAL_S: Final = 5.0
REBIRTH_ANSWER_S: Final = 10.0
"""A rebirth request not answered by an NBIRTH within this is sent again (``due``)."""
REBIRTH_RETRIES: Final = 3
"""Times an unanswered request is sent again (a node that never answers is not asked forever)."""
HISTORY_MARGIN_MS: Final = 60_000
"""Transitions asked for again from this long before the last message received in order: a
transition is published a little after it happened (the node's next report), so one stamped
before that message may have come after it."""
_MESSAGE_TYPES: Final = {t.value: t for t in MessageType}
_SIGNED_BITS: Final[dict[int, int]] = {
    DataType.INT8: 8,
    DataType.INT16: 16,
    DataType.INT32: 32,
    DataType.INT64: 64,
}


@dataclass(frozen=True, slots=True)
class Outgoing:
    topic: str
    payload: bytes
    qos: int = 0
    retain: bool = False


SampleRow = tuple[int, str, str, str, str, "MetricValue | None", bool]
"""One metric value as received: (time_ms, group, node, device, metric, value, historical),
the fields of ``Sample``."""
SeriesName = tuple[str, str, str, str]
"""(group, node, device, metric): one metric of one device (device empty: the node's own)."""


class Sample(NamedTuple):
    """One metric value as received, for the history (``SampleRow`` with its fields named)."""

    time_ms: int
    group: str
    node: str
    device: str
    metric: str
    value: MetricValue | None
    historical: bool


class SeriesIds:
    """Every series (``SeriesName``) numbered once, in the order first seen: a value is
    recorded with its series' number, and the recorder makes the four names' columns from the
    numbers in one step (four strings a value cost the recorder more than the rest of it).
    Only ever added to; read by the recorder's thread up to the length it sees."""

    __slots__ = ("_ids", "_lock", "names")

    def __init__(self) -> None:
        self.names: list[SeriesName] = []
        self._ids: dict[SeriesName, int] = {}
        self._lock = threading.Lock()
        """A new series numbered by one thread at a time (the recorder's numbers the rows of a
        write that failed, to keep them)."""

    def id(self, group: str, node: str, device: str, metric: str) -> int:
        key = (group, node, device, metric)
        found = self._ids.get(key)
        if found is None:
            with self._lock:
                found = self._ids.get(key)
                if found is None:
                    found = len(self.names)
                    self.names.append(key)
                    self._ids[key] = found
        return found


class SampleColumns:
    """Values received, for the history, as columns (row ``i``: ``times_ms[i]``, ``series[i]``
    of ``SeriesIds``, ``values[i]``, ``historical[i]``): the host appends to them as it reads
    each metric and the recorder turns them into Arrow columns without a pass of Python per row.
    Plain lists of numbers and strings besides: nothing the garbage collector tracks per value
    (a plant's second of values, some 100 000, waits in the recorder; as ``NamedTuple`` rows,
    which the collector never stops tracking, every full collection walked them all)."""

    __slots__ = ("historical", "series", "times_ms", "values")

    def __init__(self) -> None:
        self.times_ms: list[int] = []
        self.series: list[int] = []
        self.values: list[MetricValue | None] = []
        self.historical: list[bool] = []

    def __len__(self) -> int:
        return len(self.times_ms)

    def extend(self, other: SampleColumns) -> None:
        self.times_ms += other.times_ms
        self.series += other.series
        self.values += other.values
        self.historical += other.historical

    def append(self, row: SampleRow, series: SeriesIds) -> None:
        """One row given by name (the slow way: tests, a write that failed)."""
        time_ms, group, node, device, metric, value, historical = row
        self.times_ms.append(time_ms)
        self.series.append(series.id(group, node, device, metric))
        self.values.append(value)
        self.historical.append(historical)

    def rows(self, names: Sequence[SeriesName]) -> list[Sample]:
        """The rows with their series' names."""
        return [
            Sample(t, *names[s], v, h)
            for t, s, v, h in zip(
                self.times_ms, self.series, self.values, self.historical, strict=True
            )
        ]


@dataclass(slots=True)
class _Known:
    """A metric a birth named, with what handling its values needs, worked out once: a DDATA
    names its metrics by alias only, tens of them a message, many messages a second."""

    series: int
    """Its number in the host's ``SeriesIds``."""
    device: str | None
    name: str
    datatype: int
    alarm: bool
    """An ``Alarm/...`` metric."""
    active: bool
    """An ``Alarm/<id>/Active``: applied after the message's other metrics."""


def _active_last(entry: tuple[_Known, Payload.Metric]) -> bool:
    """Sort key: an alarm's ``Active`` after its priority and text (a stable sort keeps the
    message's order otherwise)."""
    return entry[0].active


def _known(series: int, device: str | None, name: str, datatype: int) -> _Known:
    alarm = name.startswith(ALARM_PREFIX)
    return _Known(series, device, name, datatype, alarm, alarm and name.endswith(ACTIVE))


@dataclass(slots=True)
class Answer:
    """What one message asks of the host's surroundings."""

    publish: list[Outgoing] = field(default_factory=list)
    columns: SampleColumns = field(default_factory=SampleColumns)
    """The values to record."""
    transitions: list[AlarmTransition] = field(default_factory=list)
    names: Sequence[SeriesName] = ()
    """The host's series' names (``SeriesIds.names``), for ``samples``."""

    @property
    def samples(self) -> list[Sample]:
        """The values to record as named rows."""
        return self.columns.rows(self.names)


@dataclass(slots=True)
class _Session:
    """A node's Sparkplug session as the host follows it."""

    born: bool = False
    seq: int = 0
    aliases: dict[int, _Known] = field(default_factory=dict)
    """alias → the metric (its device, ``None`` for the node's, and name); unique across the
    node."""
    named: dict[tuple[str | None, str], _Known] = field(default_factory=dict)
    """(device, name) → the metric, as the births named it."""
    known: dict[tuple[str | None, str, int], _Known] = field(default_factory=dict)
    """Every metric any birth named, kept across births (a rebirth names the same again)."""
    born_devices: set[str] = field(default_factory=set)
    last_rebirth_s: float = -1e18
    in_order_ms: int | None = None
    """The payload time of the node's last message received in order (``None``: none yet)."""
    missed_since_ms: int | None = None
    """Messages after this time may be lost (a gap, the host's own reconnection) and no
    rebirth request has asked for them since."""
    held: str | None = None
    """A rebirth request held by the rate limit (its reason): sent once it allows."""
    awaiting: bool = False
    """A rebirth request went out and no NBIRTH came since (it is sent again after
    ``REBIRTH_ANSWER_S``: on a broker cluster that is still re-forming, a request can be lost)."""
    retries: int = 0


def state_payload(online: bool, timestamp_ms: int) -> bytes:
    """The host's STATE (Sparkplug 3.0: JSON, ``online`` and ``timestamp``)."""
    return json.dumps({"online": online, "timestamp": timestamp_ms}).encode()


def state_topic(host_id: str) -> str:
    return f"{NAMESPACE}/STATE/{host_id}"


def decode_value(metric: Payload.Metric, datatype: int) -> MetricValue | None:
    """The metric's value, signed integers given their sign back (the wire carries them in
    unsigned fields, two's complement)."""
    which = metric.WhichOneof("value")
    if which is None or metric.is_null:
        return None
    value: MetricValue = getattr(metric, which)
    if isinstance(value, int) and not isinstance(value, bool):
        return _signed(value, datatype)
    return value


def _signed(value: int, datatype: int) -> int:
    bits = _SIGNED_BITS.get(datatype)
    if bits is not None:
        value &= (1 << bits) - 1
        if value >= 1 << (bits - 1):
            value -= 1 << bits
    return value


class _Received:
    """One message being handled: whose it is and what it asks, with what each of its values
    needs worked out once (a DDATA brings tens)."""

    __slots__ = (
        "answer",
        "device",
        "device_name",
        "device_view",
        "group",
        "live",
        "node",
        "now_s",
        "payload",
        "session",
        "stamp_ms",
        "view",
    )

    def __init__(
        self,
        session: _Session,
        view: NodeView,
        device: str | None,
        *,
        payload: Payload,
        stamp_ms: int,
        now_s: float,
        answer: Answer,
    ) -> None:
        self.session = session
        self.view = view
        self.device = device
        self.payload = payload
        self.stamp_ms = stamp_ms
        self.now_s = now_s
        self.answer = answer
        self.group = view.group
        self.node = view.node
        self.device_name = device or ""
        self.device_view = view.devices[device] if device is not None else None
        self.live = view.metrics if self.device_view is None else self.device_view.metrics
        """The live values this message's metrics update."""


class HostApplication:
    """The host's view of every edge node of its groups (``groups`` empty: all)."""

    def __init__(
        self,
        host_id: str,
        groups: frozenset[str] = frozenset(),
        rebirth_interval_s: float = REBIRTH_INTERVAL_S,
    ) -> None:
        self.host_id = host_id
        self.groups = groups
        self.rebirth_interval_s = rebirth_interval_s
        self.nodes: dict[tuple[str, str], NodeView] = {}
        self.alarms = AlarmLog()
        self.series = SeriesIds()
        """Every metric's series in the history (the recorder is given the same)."""
        self._sessions: dict[tuple[str, str], _Session] = {}
        self.rebirths: Counter[str] = Counter()
        """Rebirth requests sent, by reason (seq gap, unknown alias, before birth)."""
        self.rebirths_held = 0
        """Requests not sent: one went to that node less than ``rebirth_interval_s`` ago."""
        self.stale_deaths = 0
        self.bad_messages = 0

    @property
    def unanswered(self) -> int:
        """Nodes whose messages may be lost (a gap, the host's reconnection) and whose births
        have not come since: a rebirth request held by the rate limit or not yet answered."""
        return sum(s.held is not None or s.awaiting for s in self._sessions.values())

    @property
    def subscriptions(self) -> list[str]:
        """The topic filters: the host's own STATE and every (or each named) group."""
        groups = sorted(self.groups) or ["+"]
        return [state_topic(self.host_id)] + [f"{NAMESPACE}/{g}/#" for g in groups]

    def on_message(self, topic: str, data: bytes, now_s: float) -> Answer:
        """One received message; what to publish (rebirth requests) and record."""
        answer = Answer(names=self.series.names)
        parts = topic.split("/")
        if len(parts) not in (4, 5) or parts[0] != NAMESPACE or parts[1] == "STATE":
            return answer
        group, node = parts[1], parts[3]
        if self.groups and group not in self.groups:
            return answer
        try:
            message_type = _MESSAGE_TYPES[parts[2]]
            payload = parse_payload(data)
        except (KeyError, PayloadError):
            self.bad_messages += 1
            return answer
        if message_type in (MessageType.NCMD, MessageType.DCMD):
            return answer
        key = (group, node)
        stamp_ms = payload.timestamp
        if not stamp_ms and not payload.HasField("timestamp"):
            stamp_ms = int(now_s * 1000)
        device = parts[4] if len(parts) == 5 else None
        # Looked up, made only when new (setdefault would build a view or session, with its
        # dicts, for every message).
        view = self.nodes.get(key)
        if view is None:
            view = self.nodes[key] = NodeView(group, node)
        if device is not None and device not in view.devices:
            view.devices[device] = DeviceView(device)
        session = self._sessions.get(key)
        if session is None:
            session = self._sessions[key] = _Session()
        received = _Received(
            session, view, device, payload=payload, stamp_ms=stamp_ms, now_s=now_s, answer=answer
        )
        self._dispatch(message_type, received)
        return answer

    def _dispatch(self, message_type: MessageType, received: _Received) -> None:
        session = received.session
        if message_type is MessageType.NBIRTH:
            self._node_birth(received)
            return
        if message_type is MessageType.NDEATH:
            self._node_death(received)
            return
        if not session.born:
            self._request_rebirth(received, "before birth")
            return
        payload = received.payload
        if payload.HasField("seq"):
            if payload.seq != (session.seq + 1) % SEQ_MODULO:
                session.missed_since_ms = _earliest(session.missed_since_ms, session.in_order_ms)
                self._request_rebirth(received, "seq gap")
            else:
                session.in_order_ms = received.stamp_ms
            session.seq = payload.seq
        if message_type is MessageType.NDATA:
            self._data(received)
        elif received.device is not None:
            self._device_message(message_type, received)

    # ------------------------------------------------------------ node

    def _node_birth(self, received: _Received) -> None:
        session, view, payload = received.session, received.view, received.payload
        session.born = True
        session.seq = payload.seq if payload.HasField("seq") else 0
        session.in_order_ms = received.stamp_ms
        if session.awaiting:  # the answer: the births, then the transitions asked for
            session.awaiting = False
            session.missed_since_ms = None
        session.retries = 0
        session.aliases.clear()
        session.named.clear()
        session.born_devices.clear()
        view.online = True
        view.since_ms = received.stamp_ms
        view.metrics.clear()
        for device_view in view.devices.values():  # until their DBIRTH (Sparkplug 3.0)
            if device_view.online:
                device_view.online = False
                device_view.since_ms = received.stamp_ms
        self._births(received)
        bd_seq = view.metrics.get(BD_SEQ)
        view.bd_seq = int(bd_seq.value) if bd_seq and isinstance(bd_seq.value, int) else None

    def _node_death(self, received: _Received) -> None:
        session, view = received.session, received.view
        bd_seq = next(
            (decode_value(m, DataType.INT64) for m in received.payload.metrics if m.name == BD_SEQ),
            None,
        )
        if session.born and view.bd_seq is not None and bd_seq != view.bd_seq:
            self.stale_deaths += 1  # the will of a connection before the current session
            return
        session.born = False
        session.born_devices.clear()
        if view.online:
            view.online = False
            view.since_ms = received.stamp_ms
        for device_view in view.devices.values():
            if device_view.online:
                device_view.online = False
                device_view.since_ms = received.stamp_ms

    # ------------------------------------------------------------ device

    def _device_message(self, message_type: MessageType, received: _Received) -> None:
        device = received.device
        assert device is not None
        session = received.session
        device_view = received.view.devices[device]
        if message_type is MessageType.DBIRTH:
            session.born_devices.add(device)
            device_view.online = True
            device_view.since_ms = received.stamp_ms
            self._births(received)
        elif device not in session.born_devices:
            self._request_rebirth(received, "before birth")
        elif message_type is MessageType.DDEATH:
            session.born_devices.discard(device)
            device_view.online = False
            device_view.since_ms = received.stamp_ms
        elif message_type is MessageType.DDATA:
            self._data(received)

    # ------------------------------------------------------------ metrics

    def _births(self, received: _Received) -> None:
        """A birth's metrics: names, aliases and data types learnt, every value live."""
        session, device = received.session, received.device
        aliases, named = session.aliases, session.named
        others: list[tuple[_Known, Payload.Metric]] = []
        actives: list[tuple[_Known, Payload.Metric]] = []
        unnamed = []
        for metric in received.payload.metrics:
            name = metric.name
            if not name:
                unnamed.append(metric)  # by an alias: once every name is known
                continue
            datatype = metric.datatype
            known = session.known.get((device, name, datatype))
            if known is None:
                series = self.series.id(received.group, received.node, received.device_name, name)
                known = session.known[(device, name, datatype)] = _known(
                    series, device, name, datatype
                )
            if metric.HasField("alias"):
                aliases[metric.alias] = known
            named[(device, name)] = known
            (actives if known.active else others).append((known, metric))
        for metric in unnamed:
            found = aliases.get(metric.alias) if metric.HasField("alias") else None
            if found is not None:
                (actives if found.active else others).append((found, metric))
        self._values(received, others)
        if actives:
            self._values(received, actives)

    def _data(self, received: _Received) -> None:
        if self._apply(received):
            self._request_rebirth(received, "unknown alias")

    def _apply(self, received: _Received) -> bool:
        """The message's metrics recorded and the live ones applied, an alarm's ``Active``
        after the rest (its priority and text, which the same message may give, first: a birth
        lists them after it); ``True`` when one named no metric the births did (no name, and
        no alias or an unknown one). One pass, each metric resolved and applied at once, the
        common case (not an alarm's) inline: a DDATA brings tens, a plant thousands a second."""
        session, device = received.session, received.device
        aliases, named, live = session.aliases, session.named, received.live
        columns = received.answer.columns
        add_time, add_series = columns.times_ms.append, columns.series.append
        add_value, add_historical = columns.values.append, columns.historical.append
        stamp_ms = received.stamp_ms
        alarms: list[tuple[_Known, Payload.Metric]] = []
        unknown = False
        for metric in received.payload.metrics:
            name = metric.name
            known: _Known | None
            if name:
                known = named.get((device, name)) or self._unnamed(received, name)
            else:
                alias = metric.alias  # 0 is an alias too, when the field is there
                known = aliases.get(alias) if alias or metric.HasField("alias") else None
                if known is None:
                    unknown = True
                    continue
            if known.alarm:
                alarms.append((known, metric))
                continue
            which = metric.WhichOneof("value")
            value: MetricValue | None = None
            if which is not None and not metric.is_null:
                value = getattr(metric, which)
                if type(value) is int:  # signed integers come in unsigned fields
                    value = _signed(value, metric.datatype or known.datatype)
            time_ms = metric.timestamp
            if not time_ms and not metric.HasField("timestamp"):
                time_ms = stamp_ms
            name = known.name
            historical = metric.is_historical
            add_time(time_ms)
            add_series(known.series)
            add_value(value)
            add_historical(historical)
            if not historical:
                current = live.get(name)
                if current is None:
                    live[name] = MetricState(value, time_ms)
                elif time_ms >= current.timestamp_ms:  # changed in place: no new object
                    current.value = value
                    current.timestamp_ms = time_ms
        if alarms:  # the Actives after the rest
            alarms.sort(key=_active_last)
            self._values(received, alarms)
        return unknown

    def _unnamed(self, received: _Received, name: str) -> _Known:
        """A metric a DDATA names that no birth did: recorded and applied all the same."""
        series = self.series.id(received.group, received.node, received.device_name, name)
        return _known(series, received.device, name, 0)

    def _values(self, received: _Received, metrics: list[tuple[_Known, Payload.Metric]]) -> None:
        """Each metric's value recorded, and applied to the live model unless historical."""
        live, columns = received.live, received.answer.columns
        device_view = received.device_view
        stamp_ms = received.stamp_ms
        for known, metric in metrics:
            name = known.name
            which = metric.WhichOneof("value")
            value: MetricValue | None = None
            if which is not None and not metric.is_null:
                value = getattr(metric, which)
                if type(value) is int:  # signed integers come in unsigned fields
                    value = _signed(value, metric.datatype or known.datatype)
            time_ms = metric.timestamp
            if not time_ms and not metric.HasField("timestamp"):
                time_ms = stamp_ms
            historical = metric.is_historical
            if (
                known.alarm
                and device_view is not None
                and not self._alarm(
                    received, device_view, name, value, time_ms, historical=historical
                )
            ):
                continue  # a historical transition the log already has: recorded once
            columns.times_ms.append(time_ms)
            columns.series.append(known.series)
            columns.values.append(value)
            columns.historical.append(historical)
            if not historical:
                current = live.get(name)
                if current is None:
                    live[name] = MetricState(value, time_ms)
                elif time_ms >= current.timestamp_ms:  # changed in place: no new object
                    current.value = value
                    current.timestamp_ms = time_ms

    def _alarm(
        self,
        received: _Received,
        device_view: DeviceView,
        name: str,
        value: MetricValue | None,
        time_ms: int,
        *,
        historical: bool,
    ) -> bool:
        """An ``Alarm/<id>/Active`` value that changes what the host knew is a transition;
        a historical one is one the cell kept while it could not publish, or sent again when
        asked. ``False``: a historical transition the log already had."""
        if not name.endswith(ACTIVE) or not isinstance(value, bool):
            return True
        alarm = name[len(ALARM_PREFIX) : -len(ACTIVE)]
        if not historical:
            if (device_view.value(name) is True) == value:
                return True
            if value:
                device_view.alarm_since_ms[alarm] = time_ms
            else:
                device_view.alarm_since_ms.pop(alarm, None)
        view = received.view
        transition = AlarmTransition(
            time_ms,
            view.group,
            view.node,
            device_view.name,
            alarm,
            value,
            device_view.alarm_priority(alarm),
            device_view.alarm_text(alarm),
            historical,
        )
        if not self.alarms.add(transition):
            return not historical
        received.answer.transitions.append(transition)
        return True

    # ------------------------------------------------------------ rebirth

    def _request_rebirth(self, received: _Received, reason: str) -> None:
        session = received.session
        if received.now_s - session.last_rebirth_s < self.rebirth_interval_s:
            self.rebirths_held += 1
            session.held = session.held or reason  # sent once the limit allows (``due``)
            return
        view = received.view
        received.answer.publish.append(self._rebirth(session, view, reason, received.now_s))

    def _rebirth(self, session: _Session, view: NodeView, reason: str, now_s: float) -> Outgoing:
        session.last_rebirth_s = now_s
        session.held = None
        session.awaiting = True
        self.rebirths[reason] += 1
        since = session.missed_since_ms = _earliest(session.missed_since_ms, session.in_order_ms)
        return rebirth_request(
            view.group,
            view.node,
            int(now_s * 1000),
            None if since is None else since - HISTORY_MARGIN_MS,
        )

    def on_reconnect(self, now_s: float) -> list[Outgoing]:
        """The host's connection came back after it was lost: whatever the nodes published
        meanwhile is lost to it, so every node it knew alive is asked for a rebirth (with its
        alarm transitions since), at once rather than at its next message."""
        asked = []
        for key, view in sorted(self.nodes.items()):
            session = self._sessions.get(key)
            if session is not None and session.born:
                session.missed_since_ms = _earliest(session.missed_since_ms, session.in_order_ms)
                asked.append(self._rebirth(session, view, "reconnect", now_s))
        return asked

    def due(self, now_s: float, seen_until_s: float | None = None) -> list[Outgoing]:
        """The rebirth requests the rate limit held that it allows now, and those sent again
        that no NBIRTH answered (call it every second or so: a quiet node sends nothing that
        would bring them). ``seen_until_s``: every message received before it has been handled
        (``now_s`` by default); a plant behind its messages may hold the answer, not yet
        handled, so a request is unanswered only once what came ``REBIRTH_ANSWER_S`` after it
        has been (asked again sooner, each node's births came twice, more work for a plant
        already behind)."""
        seen_s = now_s if seen_until_s is None else min(seen_until_s, now_s)
        asked = []
        for key, view in sorted(self.nodes.items()):
            session = self._sessions.get(key)
            if session is None:
                continue
            waited_s = now_s - session.last_rebirth_s
            if session.held is not None and waited_s >= self.rebirth_interval_s:
                asked.append(self._rebirth(session, view, session.held, now_s))
            elif (
                session.awaiting
                and session.retries < REBIRTH_RETRIES
                and seen_s - session.last_rebirth_s
                >= max(REBIRTH_ANSWER_S, self.rebirth_interval_s)
            ):
                session.retries += 1
                asked.append(self._rebirth(session, view, "unanswered", now_s))
        return asked


def _earliest(first: int | None, second: int | None) -> int | None:
    if first is None:
        return second
    return first if second is None else min(first, second)


def rebirth_request(group: str, node: str, now_ms: int, since_ms: int | None = None) -> Outgoing:
    """NCMD ``Node Control/Rebirth`` = true to one edge node; with ``since_ms``, its alarm
    transitions since then asked for again (``Node Control/Alarm History Since``)."""
    payload = make_payload(now_ms, None)
    add_metric(
        payload,
        alias=None,
        name=REBIRTH,
        timestamp_ms=now_ms,
        datatype=DataType.BOOLEAN,
        value=True,
    )
    if since_ms is not None:
        add_metric(
            payload,
            alias=None,
            name=ALARM_HISTORY_SINCE,
            timestamp_ms=now_ms,
            datatype=DataType.DATETIME,
            value=max(since_ms, 0),
        )
    topic = f"{NAMESPACE}/{group}/{MessageType.NCMD}/{node}"
    return Outgoing(topic, payload.SerializeToString())
