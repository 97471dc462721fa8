"""Layer: service. ``GET /metrics`` in the Prometheus text format (0.0.4), written by hand.

Names follow Prometheus conventions (base units: seconds; ``_total`` for counters).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from cobot_hmi.scanner.originator import ConnectionState, ConnectionStats

if TYPE_CHECKING:
    from cobot_hmi.service.runtime import Service

_PREFIX = "cobot_hmi_"


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
            label_text = "{" + ",".join(f'{k}="{v}"' for k, v in labels.items()) + "}"
        self.lines.append(f"{_PREFIX}{name}{label_text} {text}")

    def one(self, name: str, kind: str, help_text: str, value: float | None) -> None:
        self.metric(name, kind, help_text)
        self.sample(name, value)


def _ms_to_s(value: float | None) -> float | None:
    return None if value is None else value / 1000


def render_metrics(service: Service, stats: ConnectionStats) -> str:
    w = _Writer()
    w.metric("connection_state", "gauge", "1 for the current class 1 connection state")
    for state in ConnectionState:
        w.sample("connection_state", 1 if stats.state is state else 0, {"state": state.value})
    w.one("frames_received_total", "counter", "T→O packets received", stats.packets_in)
    w.one("packets_sent_total", "counter", "O→T packets sent", stats.packets_out)
    w.one("frame_gaps_total", "counter", "T→O sequence gaps", stats.gaps)
    w.one("frame_duplicates_total", "counter", "T→O duplicate sequence counts", stats.duplicates)
    w.one("frames_late_total", "counter", "T→O packets later than the RPI allows", stats.late)
    w.one("frames_malformed_total", "counter", "T→O packets that did not decode", stats.malformed)
    w.metric("frame_interval_seconds", "gauge", "T→O receive interval (originator's window)")
    w.sample("frame_interval_seconds", _ms_to_s(stats.interval_mean_ms), {"stat": "mean"})
    w.sample("frame_interval_seconds", _ms_to_s(stats.interval_p99_ms), {"stat": "p99"})
    w.sample("frame_interval_seconds", _ms_to_s(stats.interval_max_ms), {"stat": "max"})
    w.one("last_frame_age_seconds", "gauge", "age of the newest frame", stats.last_frame_age_s)
    hub = service.hub
    w.metric(
        "frame_receive_interval_seconds",
        "histogram",
        "interval between consecutive frames' receive times, since the service started",
    )
    for bound, count in hub.interval_histogram():
        le = "+Inf" if bound == float("inf") else f"{bound:.5f}"
        w.sample("frame_receive_interval_seconds_bucket", count, {"le": le})
    w.sample("frame_receive_interval_seconds_sum", hub.interval_sum_s)
    w.sample("frame_receive_interval_seconds_count", hub.interval_count)
    w.one("hub_frames_total", "counter", "frames handed to the broadcast loop", hub.frames_in)
    w.one(
        "hub_frames_lost_total",
        "counter",
        "frames lost before broadcasting (the loop fell behind)",
        hub.frames_lost_in_hub,
    )
    w.one("ws_clients", "gauge", "connected WebSocket clients", len(hub.clients))
    w.one(
        "ws_frames_sent_total", "counter", "frames sent to WebSocket clients", hub.frames_sent_total
    )
    w.one(
        "ws_dropped_frames_total",
        "counter",
        "frames dropped for slow WebSocket clients",
        hub.dropped_frames_total,
    )
    w.one(
        "ws_stalled_disconnects_total",
        "counter",
        "WebSocket clients disconnected because they stopped reading",
        hub.stalled_disconnects,
    )
    w.one(
        "broadcast_seconds_total",
        "counter",
        "time spent in broadcast ticks (serialization and queueing)",
        hub.tick_seconds,
    )
    w.metric("writes_total", "counter", "PATCH /api/v1/command by outcome")
    for outcome in ("confirmed", "timeout", "invalid", "refused", "unauthorized", "forbidden"):
        w.sample("writes_total", service.commander.outcomes[outcome], {"outcome": outcome})
    w.metric("logins_total", "counter", "login attempts by outcome")
    for outcome in ("ok", "failed", "throttled"):
        w.sample("logins_total", service.logins[outcome], {"outcome": outcome})
    w.one("sessions", "gauge", "live login sessions", len(service.sessions))
    w.one(
        "control_held", "gauge", "1 while someone holds control", int(bool(service.control.holder))
    )
    w.one(
        "event_write_errors_total",
        "counter",
        "events that could not be stored",
        service.store.event_write_errors,
    )
    return "\n".join(w.lines) + "\n"
