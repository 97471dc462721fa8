"""Layer: service. ``GET /metrics``: the Prometheus text format (0.0.4) written by
``prometheus_client`` from one registry per service (``ServiceMetrics``).

The registry is the service's own, never the library's global default: tests run several
services in one process, and the process's own metrics are not the HMI's. Its collectors are
custom ones (``prometheus_client.registry.Collector``): at each scrape they read the counters the
service keeps anyway (the originator's ``ConnectionStats``, the cyclic pump's, the hub's, the
write pipeline's, the alarms', the security middlewares'), so nothing on the frame path changes
and nothing is counted twice.

Names follow Prometheus conventions (base units: seconds; ``_total`` for counters, which
``prometheus_client`` writes on the samples and on HELP and TYPE of a counter family whatever
its name). Everything about one robot carries a ``robot`` label (its name); logins, sessions,
the event store and the HTTP defences are the service's own. The recorder and the Sparkplug edge
node describe their counters as ``MetricFamily`` tuples (``metric_families()``), turned into
families here.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING, Final

from prometheus_client.core import (
    CounterMetricFamily,
    GaugeMetricFamily,
    HistogramMetricFamily,
    InfoMetricFamily,
    Metric,
)
from prometheus_client.exposition import generate_latest
from prometheus_client.registry import Collector, CollectorRegistry

from cobot_hmi.scanner.originator import ConnectionState, ConnectionStats
from cobot_hmi.service.api.http_limits import ConnectionCounters
from cobot_hmi.service.api.security import REFUSAL_REASONS, SecurityCounters
from cobot_hmi.service.api.tls import ReloadingContext
from cobot_hmi.service.extensions import MetricFamily
from cobot_hmi.service.robots.link import stats_of
from cobot_hmi.service.storage.audit_chain import ChainHead

if TYPE_CHECKING:
    from cobot_hmi.service.robots.robot import RobotRuntime
    from cobot_hmi.service.runtime import Service

PREFIX: Final = "cobot_hmi_"


_WRITE_OUTCOMES: Final = ("confirmed", "timeout", "invalid", "refused", "unauthorized", "forbidden")
_LOGIN_OUTCOMES: Final = ("ok", "failed", "throttled", "forbidden", "unreachable")
"""forbidden: a directory user in no mapped group; unreachable: the directory did not answer."""
_CONNECTION_CLOSINGS: Final = ("idle_closed", "evicted", "refused")

_RobotValue = Callable[["RobotRuntime", ConnectionStats], float | None]
_Robots = list[tuple[str, "RobotRuntime", ConnectionStats]]


def _number(value: float | None) -> float:
    """A sample's value (``None``, not known yet: NaN, as Prometheus writes it)."""
    return float("nan") if value is None else float(value)


def _ms_to_s(value: float | None) -> float | None:
    return None if value is None else value / 1000


def _counter(name: str, help_text: str, labels: Iterable[str] = ()) -> CounterMetricFamily:
    return CounterMetricFamily(PREFIX + name, help_text, labels=list(labels))


def _gauge(name: str, help_text: str, labels: Iterable[str] = ()) -> GaugeMetricFamily:
    return GaugeMetricFamily(PREFIX + name, help_text, labels=list(labels))


def family_of(family: MetricFamily) -> Metric:
    """A ``MetricFamily`` tuple as prometheus_client's family (its samples' labels as given)."""
    name, kind, help_text, samples = family
    metric: Metric
    if kind == "counter":
        if not name.endswith("_total"):  # prometheus_client would append it: another name
            raise ValueError(f"{name}: a counter's name ends in _total")
        metric = CounterMetricFamily(PREFIX + name, help_text)
        sample_name = metric.name + "_total"
    elif kind == "gauge":
        metric = GaugeMetricFamily(PREFIX + name, help_text)
        sample_name = metric.name
    else:
        raise ValueError(f"{name}: a {kind!r} family is not one this service writes")
    for labels, value in samples:
        metric.add_sample(sample_name, labels, value)
    return metric


class ServiceCollector(Collector):
    """The service's and its robots' metrics, read at scrape time. ``stats`` (each robot's
    ``link.stats()``, fetched on the cyclic thread) is set just before each collection."""

    def __init__(self, service: Service) -> None:
        self._service = service
        self.stats: dict[str, ConnectionStats] = {}
        self.pump: dict[str, int] = {}
        """The cyclic pump's counters (``CyclicLoop.pump_counters``), set with ``stats``."""

    def collect(self) -> Iterator[Metric]:
        service = self._service
        robots: _Robots = [
            (name, robot, self.stats[name])
            for name, robot in service.robots.items()
            if name in self.stats
        ]
        yield from _connection_families(robots)
        yield GaugeMetricFamily(
            PREFIX + "cyclic_thread_up",
            "1 while the cyclic I/O thread runs",
            value=int(service.cyclic.alive),
        )
        yield CounterMetricFamily(
            PREFIX + "cyclic_thread_restarts_total",
            "times the cyclic I/O thread died and restarted",
            value=service.cyclic.restarts,
        )
        yield from _pump_families(self.pump)
        yield from _timing_families(robots)
        yield from _hub_families(robots)
        yield from _control_families(robots)
        logins = _counter("logins_total", "login attempts by outcome", ["outcome"])
        for outcome in _LOGIN_OUTCOMES:
            logins.add_metric([outcome], service.logins[outcome])
        yield logins
        yield GaugeMetricFamily(
            PREFIX + "sessions", "live login sessions", value=len(service.sessions)
        )
        yield CounterMetricFamily(
            PREFIX + "event_write_errors_total",
            "events lost: not stored and given up (a disk full for longer than the memory "
            "backlog lasts)",
            value=service.store.event_write_errors,
        )
        waiting = _gauge(
            "rows_waiting_for_disk",
            "rows kept in memory because the disk has no room, written once it has",
            ["what"],
        )
        waiting.add_metric(["events"], len(service.store.event_writer.waiting))
        waiting.add_metric(
            ["alarm_changes"],
            sum(len(robot.alarm_store.writer.waiting) for robot in service.robots.values()),
        )
        waiting.add_metric(["cycles"], len(service.cycles.store.writer.waiting))
        yield waiting
        backlog = service.store.audit_backlog
        yield GaugeMetricFamily(
            PREFIX + "audit_backlog",
            "audit rows and outcomes waiting in memory for room on the disk",
            value=len(backlog),
        )
        yield CounterMetricFamily(
            PREFIX + "audit_rows_lost_total",
            "refusals' audit rows dropped while the disk was full and the backlog at its limit",
            value=backlog.lost,
        )
        yield from _audit_chain_families(service.store.chain_head)
        for extension in service.extensions:  # the edge node's, the OPC UA server's, …
            yield from map(family_of, extension.metric_families())
        recorder = service.recorder
        if recorder is not None:  # the history recorder's counters (service/recording/recorder.py)
            yield from map(family_of, recorder.metric_families())
        yield from map(family_of, service.health.metric_families())  # service/health


def _audit_chain_families(head: ChainHead | None) -> Iterator[Metric]:
    """The audit chain's head as the store last read it (``storage/audit_chain.py``): a copy
    outside the database, so a rewritten chain shows against what Prometheus kept."""
    if head is None:  # the store is not open
        return
    yield GaugeMetricFamily(
        PREFIX + "audit_chain_head_row",
        "row id of the audit chain's newest seal (0: none yet)",
        value=head.row_id or 0,
    )
    yield InfoMetricFamily(
        PREFIX + "audit_chain_head",
        "the audit chain's newest seal: its number, row and first 16 hex digits of its SHA-256",
        value={"seal": str(head.seq), "row": str(head.row_id or 0), "sha256": head.hash[:16]},
    )


def _per_robot(
    family: CounterMetricFamily | GaugeMetricFamily, robots: _Robots, value: _RobotValue
) -> Metric:
    for name, robot, stats in robots:
        family.add_metric([name], _number(value(robot, stats)))
    return family


def _connection_families(robots: _Robots) -> Iterator[Metric]:
    state = _gauge(
        "connection_state", "1 for the current class 1 connection state", ["robot", "state"]
    )
    for name, _, stats in robots:
        for one in ConnectionState:
            state.add_metric([name, one.value], 1 if stats.state is one else 0)
    yield state
    counters: tuple[tuple[str, str, _RobotValue], ...] = (
        ("frames_received_total", "T→O packets received", lambda r, s: s.packets_in),
        ("packets_sent_total", "O→T packets sent", lambda r, s: s.packets_out),
        (
            "frame_gaps_total",
            "T→O packets lost on the way (CIP sequence count jumps)",
            lambda r, s: s.gaps,
        ),
        ("frame_duplicates_total", "T→O duplicate sequence counts", lambda r, s: s.duplicates),
        (
            "frames_late_total",
            "T→O frames more than 1.5 x the granted interval after the one before (any reason)",
            lambda r, s: s.late,
        ),
        ("frames_malformed_total", "T→O packets that did not decode", lambda r, s: s.malformed),
        ("connects_total", "times the connection came up", lambda r, s: r.connection.connects),
        (
            "connection_losses_total",
            "times a connection was lost",
            lambda r, s: r.connection.losses,
        ),
    )
    for metric, help_text, value in counters:
        yield _per_robot(_counter(metric, help_text, ["robot"]), robots, value)


_PUMP_COUNTERS: Final = (
    ("sent", "cyclic_pump_datagrams_sent_total", "O→T datagrams the cyclic pump sent"),
    (
        "send_errors",
        "cyclic_pump_send_errors_total",
        "O→T datagrams the kernel refused to send (the pump goes on with the next)",
    ),
    (
        "received",
        "cyclic_pump_datagrams_received_total",
        "datagrams the cyclic pump read from the UDP 2222 socket (every robot's T→O)",
    ),
    (
        "ring_overflows",
        "cyclic_pump_ring_overflows_total",
        "received datagrams the pump's ring gave up, oldest first, because the service did not "
        "take them in time (frames lost inside this process, not on the wire)",
    ),
    (
        "wakeups",
        "cyclic_pump_wakeups_total",
        "times the pump's thread woke (a send due, a datagram in, a timeout)",
    ),
)


def _pump_families(pump: dict[str, int]) -> Iterator[Metric]:
    """The cyclic pump of the service's UDP 2222 socket (``native/cyclic_pump.c``): one for
    every robot, so no robot label. Counted since the cyclic thread last started (a restart
    opens a new socket: a counter reset, as Prometheus expects of a restart); absent while the
    thread is down."""
    if not pump:
        return
    for key, name, help_text in _PUMP_COUNTERS:
        yield CounterMetricFamily(PREFIX + name, help_text, value=pump[key])
    yield GaugeMetricFamily(
        PREFIX + "cyclic_pump_send_late_max_seconds",
        "the latest an O→T datagram left after its due time, since the cyclic thread started",
        value=pump["max_late_ns"] / 1e9,
    )
    yield GaugeMetricFamily(
        PREFIX + "cyclic_pump_realtime",
        "1 if the pump's thread got real-time scheduling (SCHED_FIFO), 0 if it runs as others",
        value=pump["realtime"],
    )


def _timing_families(robots: _Robots) -> Iterator[Metric]:
    interval = _gauge(
        "frame_interval_seconds", "T→O receive interval (originator's window)", ["robot", "stat"]
    )
    for name, _, stats in robots:
        for stat, value_ms in (
            ("mean", stats.interval_mean_ms),
            ("p99", stats.interval_p99_ms),
            ("max", stats.interval_max_ms),
        ):
            interval.add_metric([name, stat], _number(_ms_to_s(value_ms)))
    yield interval
    yield _per_robot(
        _gauge("last_frame_age_seconds", "age of the newest frame", ["robot"]),
        robots,
        lambda r, s: s.last_frame_age_s,
    )
    histogram = HistogramMetricFamily(
        PREFIX + "frame_receive_interval_seconds",
        "interval between consecutive frames' receive times, since the service started",
        labels=["robot"],
    )
    for name, robot, _ in robots:
        intervals = robot.intervals
        # The bounds as this service has always written them (le="0.00100"): a dashboard's
        # series keep their identity. The count is the +Inf bucket's.
        buckets = [
            ("+Inf" if bound == float("inf") else f"{bound:.5f}", float(count))
            for bound, count in intervals.histogram()
        ]
        histogram.add_metric([name], buckets, intervals.sum_s)
    yield histogram
    # Every consumer of every robot's frames, by name: what its bounded queue dropped.
    dropped = _counter(
        "consumer_dropped_frames_total",
        "frames a consumer's queue dropped because it fell behind (robots.frame_notifier)",
        ["robot", "consumer"],
    )
    for name, robot, _ in robots:
        for registration in robot.frames.registrations:
            dropped.add_metric([name, registration.name], registration.dropped)
    yield dropped


def _hub_families(robots: _Robots) -> Iterator[Metric]:
    families: tuple[tuple[str, str, str, _RobotValue], ...] = (
        (
            "counter",
            "hub_frames_total",
            "frames handed to the broadcast loop",
            lambda r, s: r.intervals.frames_in,
        ),
        (
            "counter",
            "hub_frames_lost_total",
            "frames lost before broadcasting (the loop fell behind)",
            lambda r, s: r.frames.dropped_by(r.hub.name),
        ),
        ("gauge", "ws_clients", "connected WebSocket clients", lambda r, s: len(r.hub.clients)),
        (
            "counter",
            "ws_frames_sent_total",
            "frames sent to WebSocket clients",
            lambda r, s: r.hub.frames_sent_total,
        ),
        (
            "counter",
            "ws_dropped_frames_total",
            "frames dropped for slow WebSocket clients",
            lambda r, s: r.hub.dropped_frames_total,
        ),
        (
            "counter",
            "ws_stalled_disconnects_total",
            "WebSocket clients disconnected because they stopped reading",
            lambda r, s: r.hub.stalled_disconnects,
        ),
        (
            "counter",
            "broadcast_seconds_total",
            "time spent in broadcast ticks (serialization and queueing)",
            lambda r, s: r.hub.tick_seconds,
        ),
    )
    for kind, metric, help_text, value in families:
        family = _counter if kind == "counter" else _gauge
        yield _per_robot(family(metric, help_text, ["robot"]), robots, value)


def _control_families(robots: _Robots) -> Iterator[Metric]:
    writes = _counter(
        "writes_total", "writes through the write pipeline by outcome", ["robot", "outcome"]
    )
    for name, robot, _ in robots:
        for outcome in _WRITE_OUTCOMES:
            writes.add_metric([name, outcome], robot.writes.outcomes[outcome])
    yield writes
    yield _per_robot(
        _gauge("control_held", "1 while someone holds control", ["robot"]),
        robots,
        lambda r, s: int(r.control.holder is not None),
    )
    alarms = _gauge(
        "alarms",
        "alarms by priority and what they are: active, unacknowledged, shelved, suppressed",
        ["robot", "priority", "state"],
    )
    for name, robot, _ in robots:
        for (priority, what), count in robot.alarms.counts().items():
            alarms.add_metric([name, priority, what], count)
    yield alarms
    yield _per_robot(
        _gauge(
            "alarm_evaluation_failed",
            "1 when the frame alarms stopped after an error (see the log)",
            ["robot"],
        ),
        robots,
        lambda r, s: int(r.alarms.failed),
    )
    yield _per_robot(
        _counter(
            "alarm_write_errors_total",
            "alarm changes lost: not stored and given up (a disk full for longer than the "
            "memory backlog lasts)",
            ["robot"],
        ),
        robots,
        lambda r, s: r.alarm_store.write_errors,
    )


class HttpCollector(Collector):
    """The HTTP defences' counters (``security``, ``http_limits``), read at scrape time.
    ``connections`` gives the connection bounds' counters once the server made them (``None``
    when the app runs without ``server.uvicorn_config``, as under a test client)."""

    def __init__(
        self,
        refusals: SecurityCounters,
        connections: Callable[[], ConnectionCounters | None],
        tls: Callable[[], ReloadingContext | None] = lambda: None,
    ) -> None:
        self._refusals = refusals
        self._connections = connections
        self._tls = tls

    def collect(self) -> Iterator[Metric]:
        refusals = _counter(
            "http_refusals_total", "HTTP requests refused by the security checks", ["reason"]
        )
        for reason in REFUSAL_REASONS:
            refusals.add_metric([reason], self._refusals.refusals[reason])
        yield refusals
        connections = self._connections()
        if connections is not None:
            closed = _counter(
                "http_connections_closed_total",
                "TCP connections the service closed to stay within its bounds (idle_closed: "
                "no request in time; evicted: idle, made room for a new one; refused: new, "
                "every slot busy)",
                ["reason"],
            )
            for reason in _CONNECTION_CLOSINGS:
                closed.add_metric([reason], connections.closed[reason])
            yield closed
        tls = self._tls()
        if tls is not None:  # HTTPS served by the service itself
            yield CounterMetricFamily(
                PREFIX + "tls_certificate_reloads",
                "times a replaced certificate and key were loaded without a restart",
                value=tls.reloads,
            )
            yield CounterMetricFamily(
                PREFIX + "tls_certificate_reload_failures",
                "replaced certificate files that could not be loaded (the last good pair stays)",
                value=tls.failures,
            )
            yield GaugeMetricFamily(
                PREFIX + "tls_certificate_expiry_timestamp_seconds",
                "when the certificate served now expires (notAfter, seconds since the epoch)",
                value=tls.not_after_s,
            )


class ServiceMetrics:
    """One service's registry: its ``ServiceCollector`` and the app's ``HttpCollector``."""

    def __init__(self, service: Service, http: HttpCollector) -> None:
        self._service = service
        self._collector = ServiceCollector(service)
        self.registry = CollectorRegistry(auto_describe=False)
        self.registry.register(self._collector)
        self.registry.register(http)

    async def exposition(self) -> bytes:
        """The text of one scrape. Each robot's connection statistics come from the cyclic
        thread first (a consistent snapshot); the collection after them is synchronous, so no
        other scrape on this event loop can swap the snapshot in between."""
        stats = await stats_of([robot.link for robot in self._service.robots.values()])
        # After the statistics: the pump's counts include every packet they counted.
        pump = await self._service.cyclic.pump_counters()
        self._collector.stats, self._collector.pump = stats, pump
        return generate_latest(self.registry)
