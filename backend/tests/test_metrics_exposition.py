"""``GET /metrics`` through prometheus_client keeps the exposition of 58f13a2, where it was
written by hand: every family's name, type and label names, the histogram's bounds as written,
the content type. ``legacy/metrics-58f13a2.json`` is that code's scrape of a service with the
recorder and a Sparkplug edge node (``legacy/make_legacy.py``); the same kind of service runs
here and its scrape is parsed by prometheus_client's own parser.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import pytest
from prometheus_client import REGISTRY, generate_latest
from prometheus_client.core import Metric
from prometheus_client.parser import text_string_to_metric_families
from prometheus_client.registry import Collector, CollectorRegistry

from cobot_hmi.service.api.metrics import family_of
from legacy.make_legacy import histogram_bounds, metrics_shape
from mosquitto_support import needs_mosquitto
from sparkplug_support import cell

LEGACY = Path(__file__).parent / "legacy"

# Families added after 58f13a2: the history closer's (a journal becoming its segment in a process
# of its own), every frame consumer's drops (robots.frame_notifier), the audit's on a full disk
# (outcomes kept in memory until the disk takes them), the rows of the events, alarms and
# cycles waiting for the disk likewise, the cyclic pump's, and robot health's (service.health).
ADDED_SINCE_58F13A2: dict[str, Any] = {
    "cobot_hmi_health_frames_fed": {
        "type": "counter",
        "samples": {"cobot_hmi_health_frames_fed_total": ["robot"]},
    },
    "cobot_hmi_health_cycles_fed": {
        "type": "counter",
        "samples": {"cobot_hmi_health_cycles_fed_total": ["robot"]},
    },
    "cobot_hmi_health_cycles_refused": {
        "type": "counter",
        "samples": {"cobot_hmi_health_cycles_refused_total": ["robot"]},
    },
    "cobot_hmi_health_failures": {
        "type": "counter",
        "samples": {"cobot_hmi_health_failures_total": [""]},
    },
    "cobot_hmi_health_cpu_seconds": {
        "type": "counter",
        "samples": {"cobot_hmi_health_cpu_seconds_total": [""]},
    },
    "cobot_hmi_history_journals_closing": {
        "type": "gauge",
        "samples": {"cobot_hmi_history_journals_closing": [""]},
    },
    "cobot_hmi_history_journal_close_errors": {
        "type": "counter",
        "samples": {"cobot_hmi_history_journal_close_errors_total": [""]},
    },
    "cobot_hmi_consumer_dropped_frames": {
        "type": "counter",
        "samples": {"cobot_hmi_consumer_dropped_frames_total": ["consumer,robot"]},
    },
    "cobot_hmi_sparkplug_buffer_set_aside": {
        "type": "counter",
        "samples": {"cobot_hmi_sparkplug_buffer_set_aside_total": [""]},
    },
    "cobot_hmi_cyclic_pump_datagrams_sent": {
        "type": "counter",
        "samples": {"cobot_hmi_cyclic_pump_datagrams_sent_total": [""]},
    },
    "cobot_hmi_cyclic_pump_send_errors": {
        "type": "counter",
        "samples": {"cobot_hmi_cyclic_pump_send_errors_total": [""]},
    },
    "cobot_hmi_cyclic_pump_datagrams_received": {
        "type": "counter",
        "samples": {"cobot_hmi_cyclic_pump_datagrams_received_total": [""]},
    },
    "cobot_hmi_cyclic_pump_ring_overflows": {
        "type": "counter",
        "samples": {"cobot_hmi_cyclic_pump_ring_overflows_total": [""]},
    },
    "cobot_hmi_cyclic_pump_wakeups": {
        "type": "counter",
        "samples": {"cobot_hmi_cyclic_pump_wakeups_total": [""]},
    },
    "cobot_hmi_cyclic_pump_send_late_max_seconds": {
        "type": "gauge",
        "samples": {"cobot_hmi_cyclic_pump_send_late_max_seconds": [""]},
    },
    "cobot_hmi_cyclic_pump_realtime": {
        "type": "gauge",
        "samples": {"cobot_hmi_cyclic_pump_realtime": [""]},
    },
    "cobot_hmi_rows_waiting_for_disk": {
        "type": "gauge",
        "samples": {"cobot_hmi_rows_waiting_for_disk": ["what"]},
    },
    "cobot_hmi_audit_backlog": {
        "type": "gauge",
        "samples": {"cobot_hmi_audit_backlog": [""]},
    },
    "cobot_hmi_audit_rows_lost": {
        "type": "counter",
        "samples": {"cobot_hmi_audit_rows_lost_total": [""]},
    },
    "cobot_hmi_audit_chain_head_row": {
        "type": "gauge",
        "samples": {"cobot_hmi_audit_chain_head_row": [""]},
    },
    "cobot_hmi_audit_chain_head_info": {
        "type": "gauge",
        "samples": {"cobot_hmi_audit_chain_head_info": ["row,seal,sha256"]},
    },
}


@needs_mosquitto
@pytest.mark.timeout(180)
async def test_metrics_keep_the_names_types_and_labels_of_58f13a2(
    tmp_path: Path, plc_host: str
) -> None:
    before: dict[str, Any] = json.loads((LEGACY / "metrics-58f13a2.json").read_text())
    async with cell(tmp_path, plc_host) as c, c.running.client() as client:
        answer = await client.get("/metrics")
    assert answer.status_code == 200
    assert answer.headers["content-type"] == before["content_type"]
    text = answer.text
    now = metrics_shape(text)

    def without_help(shape: dict[str, Any]) -> dict[str, Any]:
        return {
            name: {"type": family["type"], "samples": family["samples"]}
            for name, family in shape.items()
        }

    # Every family of 58f13a2 as it was, in the same order; the families added since are the
    # ones named here, each with its type and labels.
    kept = {name: family for name, family in now.items() if name in before["families"]}
    assert without_help(kept) == without_help(before["families"])
    assert list(kept) == list(before["families"])
    added = {name: family for name, family in now.items() if name not in before["families"]}
    assert without_help(added) == ADDED_SINCE_58F13A2
    assert all(family["help"] for family in now.values())
    assert histogram_bounds(text) == before["histogram_le"]
    # Each family once, HELP then TYPE, as Prometheus reads it.
    for name, family in now.items():
        written = name + "_total" if family["type"] == "counter" else name
        assert text.count(f"# TYPE {written} {family['type']}\n") == 1, name
    # The service's registry is its own: the process-wide default one has none of it.
    assert b"cobot_hmi_" not in generate_latest(REGISTRY)


def test_a_reported_family_keeps_its_samples_labels() -> None:
    counter = family_of(
        (
            "sparkplug_messages_total",
            "counter",
            "Sparkplug messages by type",
            [({"type": "NBIRTH"}, 1.0), ({"robot": "left", "type": "DBIRTH"}, 2.0)],
        )
    )
    text = generate_latest(_registry(counter)).decode()
    assert "# TYPE cobot_hmi_sparkplug_messages_total counter\n" in text
    assert 'cobot_hmi_sparkplug_messages_total{type="NBIRTH"} 1.0\n' in text
    assert 'cobot_hmi_sparkplug_messages_total{robot="left",type="DBIRTH"} 2.0\n' in text
    gauge = family_of(("history_recording", "gauge", "1 while recording", [({}, 0.0)]))
    parsed = list(text_string_to_metric_families(generate_latest(_registry(gauge)).decode()))
    assert [(f.name, f.type, [s.value for s in f.samples]) for f in parsed] == [
        ("cobot_hmi_history_recording", "gauge", [0.0])
    ]
    with pytest.raises(ValueError, match="_total"):
        family_of(("frames", "counter", "a counter without _total", []))


class _Families(Collector):
    def __init__(self, *families: Metric) -> None:
        self._families = families

    def collect(self) -> Iterable[Metric]:
        return self._families


def _registry(*families: Metric) -> CollectorRegistry:
    registry = CollectorRegistry(auto_describe=False)
    registry.register(_Families(*families))
    return registry
