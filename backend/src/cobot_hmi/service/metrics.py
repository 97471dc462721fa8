"""Layer: service. ``GET /metrics`` in the Prometheus text format (0.0.4), written by hand.

Names follow Prometheus conventions (base units: seconds; ``_total`` for counters). Everything
about one robot carries a ``robot`` label (its name); logins, sessions and the event store are
the service's own. Each metric's HELP and TYPE come once, before all robots' samples.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from cobot_hmi.scanner.originator import ConnectionState, ConnectionStats

if TYPE_CHECKING:
    from cobot_hmi.service.robot import RobotRuntime
    from cobot_hmi.service.runtime import Service

_PREFIX = "cobot_hmi_"


def _escape(value: str) -> str:
    """A label value as the text format quotes it (backslash, quote, newline escaped)."""
    return value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")


class _Writer:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def metric(self, name: str, kind: str, help_text: str) -> None:
        self.lines.append(f"# HELP {_PREFIX}{name} {help_text}")
        self.lines.append(f"# TYPE {_PREFIX}{name} {kind}")

    def sample(self, name: str, value: float | None, labels: dict[str, str] | None = None) -> None:
        text = "NaN" if value is None else repr(float(value))
        label_text = ""
        if labels:
            label_text = "{" + ",".join(f'{k}="{_escape(v)}"' for k, v in labels.items()) + "}"
        self.lines.append(f"{_PREFIX}{name}{label_text} {text}")

    def one(self, name: str, kind: str, help_text: str, value: float | None) -> None:
        self.metric(name, kind, help_text)
        self.sample(name, value)


def _ms_to_s(value: float | None) -> float | None:
    return None if value is None else value / 1000


_WRITE_OUTCOMES = ("confirmed", "timeout", "invalid", "refused", "unauthorized", "forbidden")


def render_metrics(service: Service, stats: dict[str, ConnectionStats]) -> str:
    """The exposition text; ``stats`` by robot name (``link.stats()`` of each, fetched first)."""
    w = _Writer()
    robots: list[tuple[RobotRuntime, ConnectionStats, dict[str, str]]] = [
        (robot, stats[name], {"robot": name})
        for name, robot in service.robots.items()
        if name in stats
    ]

    def per_robot(name: str, kind: str, help_text: str, value: Callable[..., float | None]) -> None:
        w.metric(name, kind, help_text)
        for robot, robot_stats, label in robots:
            w.sample(name, value(robot, robot_stats), label)

    w.metric("connection_state", "gauge", "1 for the current class 1 connection state")
    for _, robot_stats, label in robots:
        for state in ConnectionState:
            w.sample(
                "connection_state",
                1 if robot_stats.state is state else 0,
                {**label, "state": state.value},
            )
    per_robot("frames_received_total", "counter", "T→O packets received", lambda r, s: s.packets_in)
    per_robot("packets_sent_total", "counter", "O→T packets sent", lambda r, s: s.packets_out)
    per_robot("frame_gaps_total", "counter", "T→O sequence gaps", lambda r, s: s.gaps)
    per_robot(
        "frame_duplicates_total",
        "counter",
        "T→O duplicate sequence counts",
        lambda r, s: s.duplicates,
    )
    per_robot(
        "frames_late_total", "counter", "T→O packets later than the RPI allows", lambda r, s: s.late
    )
    per_robot(
        "frames_malformed_total",
        "counter",
        "T→O packets that did not decode",
        lambda r, s: s.malformed,
    )
    per_robot("connects_total", "counter", "times the connection came up", lambda r, s: r.connects)
    per_robot(
        "connection_losses_total", "counter", "times a connection was lost", lambda r, s: r.losses
    )
    w.metric("cyclic_thread_up", "gauge", "1 while the cyclic I/O thread runs")
    w.sample("cyclic_thread_up", int(service.cyclic.alive))
    w.metric(
        "cyclic_thread_restarts_total", "counter", "times the cyclic I/O thread died and restarted"
    )
    w.sample("cyclic_thread_restarts_total", service.cyclic.restarts)
    w.metric("frame_interval_seconds", "gauge", "T→O receive interval (originator's window)")
    for _, robot_stats, label in robots:
        w.sample(
            "frame_interval_seconds",
            _ms_to_s(robot_stats.interval_mean_ms),
            {**label, "stat": "mean"},
        )
        w.sample(
            "frame_interval_seconds",
            _ms_to_s(robot_stats.interval_p99_ms),
            {**label, "stat": "p99"},
        )
        w.sample(
            "frame_interval_seconds",
            _ms_to_s(robot_stats.interval_max_ms),
            {**label, "stat": "max"},
        )
    per_robot(
        "last_frame_age_seconds",
        "gauge",
        "age of the newest frame",
        lambda r, s: s.last_frame_age_s,
    )
    w.metric(
        "frame_receive_interval_seconds",
        "histogram",
        "interval between consecutive frames' receive times, since the service started",
    )
    for robot, _, label in robots:
        hub = robot.hub
        for bound, count in hub.interval_histogram():
            le = "+Inf" if bound == float("inf") else f"{bound:.5f}"
            w.sample("frame_receive_interval_seconds_bucket", count, {**label, "le": le})
        w.sample("frame_receive_interval_seconds_sum", hub.interval_sum_s, label)
        w.sample("frame_receive_interval_seconds_count", hub.interval_count, label)
    per_robot(
        "hub_frames_total",
        "counter",
        "frames handed to the broadcast loop",
        lambda r, s: r.hub.frames_in,
    )
    per_robot(
        "hub_frames_lost_total",
        "counter",
        "frames lost before broadcasting (the loop fell behind)",
        lambda r, s: r.hub.frames_lost_in_hub,
    )
    per_robot("ws_clients", "gauge", "connected WebSocket clients", lambda r, s: len(r.hub.clients))
    per_robot(
        "ws_frames_sent_total",
        "counter",
        "frames sent to WebSocket clients",
        lambda r, s: r.hub.frames_sent_total,
    )
    per_robot(
        "ws_dropped_frames_total",
        "counter",
        "frames dropped for slow WebSocket clients",
        lambda r, s: r.hub.dropped_frames_total,
    )
    per_robot(
        "ws_stalled_disconnects_total",
        "counter",
        "WebSocket clients disconnected because they stopped reading",
        lambda r, s: r.hub.stalled_disconnects,
    )
    per_robot(
        "broadcast_seconds_total",
        "counter",
        "time spent in broadcast ticks (serialization and queueing)",
        lambda r, s: r.hub.tick_seconds,
    )
    w.metric("writes_total", "counter", "writes through the write pipeline by outcome")
    for robot, _, label in robots:
        for outcome in _WRITE_OUTCOMES:
            w.sample(
                "writes_total", robot.commander.outcomes[outcome], {**label, "outcome": outcome}
            )
    per_robot(
        "control_held",
        "gauge",
        "1 while someone holds control",
        lambda r, s: int(r.control.holder is not None),
    )
    w.metric(
        "alarms",
        "gauge",
        "alarms by priority and what they are: active, unacknowledged, shelved",
    )
    for robot, _, label in robots:
        for (priority, what), count in robot.alarms.counts().items():
            w.sample("alarms", count, {**label, "priority": priority, "state": what})
    per_robot(
        "alarm_evaluation_failed",
        "gauge",
        "1 when the frame alarms stopped after an error (see the log)",
        lambda r, s: int(r.alarms.failed),
    )
    per_robot(
        "alarm_write_errors_total",
        "counter",
        "alarm changes that could not be stored",
        lambda r, s: r.alarm_store.write_errors,
    )
    w.metric("logins_total", "counter", "login attempts by outcome")
    for outcome in ("ok", "failed", "throttled"):
        w.sample("logins_total", service.logins[outcome], {"outcome": outcome})
    w.one("sessions", "gauge", "live login sessions", len(service.sessions))
    w.one(
        "event_write_errors_total",
        "counter",
        "events that could not be stored",
        service.store.event_write_errors,
    )
    edge_node = service.edge_node
    if edge_node is not None:  # the Sparkplug B edge node's own counters (cobot_hmi.sparkplug)
        for name, kind, help_text, samples in edge_node.metric_families():
            w.metric(name, kind, help_text)
            for labels, value in samples:
                w.sample(name, value, labels)
    recorder = service.recorder
    if recorder is not None:  # the history recorder's counters (service/recorder.py)
        for name, kind, help_text, samples in recorder.metric_families():
            w.metric(name, kind, help_text)
            for labels, value in samples:
                w.sample(name, value, labels)
    return "\n".join(w.lines) + "\n"
