"""Benchmark of issue 15 (``bench/sparkplug``): the service as a Sparkplug B edge node.

Four emulated robots (``--robots``) at RPI 10 ms, each its own process, and the service holding
a class 1 connection to each; a local Mosquitto (Debian's ``mosquitto``, on a fresh loopback
address) and a subscriber in this process reading ``spBv1.0/#``. Two conditions in the same
run, alternating ``--cycles`` times (the machine's other load drifts; both must see it): the
service started without ``--mqtt-url`` (off) and with it (on), ``--seconds`` of each in all.
The emulators run through both; the service is restarted for each phase, and measured after
``--settle-seconds``.

Printed: messages/s and bytes/s published (the service's ``sparkplug_*`` counters) and received
(the subscriber); the service's CPU % of a core on and off, their difference (the publisher's
cost) per robot; Mosquitto's CPU; latency robot frame → subscriber, p50/p99 (each DDATA's newest
metric timestamp, the frame's kernel receive time in the service, to the subscriber's receive
time: both clocks are this machine's); per robot the cyclic receive interval p99 (the
``frame_receive_interval_seconds`` histogram between two scrapes) on and off and their ratio.
A probe published by this process every 50 ms during the "on" phases gives the machine's own
MQTT latency (this process → Mosquitto → this process) as a baseline in the same run.
Targets: latency p99 ≤ 50 ms, ratio ≤ 1.1, publisher CPU ≤ 5 % of a core per robot.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from proc_stats import own_cpu_s, process_cpu_s
from service_bench_support import (
    Cell,
    _wait,
    broker,
    emulated_cell,
    histogram_quantile,
    metrics,
    stop_process,
)

from cobot_hmi.sparkplug.payload import parse_payload

HISTOGRAM = "cobot_hmi_frame_receive_interval_seconds"
PROBE_TOPIC = "bench/probe"
PROBE_PERIOD_S = 0.05


@dataclass
class Subscription:
    """What the subscriber saw: DDATA latencies, messages and bytes (its own thread)."""

    latencies_s: list[float] = field(default_factory=list)
    in_service_s: list[float] = field(default_factory=list)
    """Newest frame's receive time → the payload's timestamp (taken when it was built)."""
    probe_s: list[float] = field(default_factory=list)
    """This process → Mosquitto → this process: the machine's own MQTT latency, a baseline."""
    messages: int = 0
    bytes: int = 0
    recording: bool = False
    lock: threading.Lock = field(default_factory=threading.Lock)

    def on_message(
        self, _client: mqtt.Client, _userdata: object, message: mqtt.MQTTMessage
    ) -> None:
        received = time.time()
        if not self.recording:
            return
        data = bytes(message.payload)
        if message.topic == PROBE_TOPIC:
            with self.lock:
                self.probe_s.append(received - float(data))
            return
        latency = in_service = None
        if "/DDATA/" in message.topic:
            payload = parse_payload(data)
            stamps = [m.timestamp for m in payload.metrics if m.timestamp]
            if stamps:
                latency = received - max(stamps) / 1000
                in_service = (payload.timestamp - max(stamps)) / 1000
        with self.lock:
            self.messages += 1
            self.bytes += len(data)
            if latency is not None and in_service is not None:
                self.latencies_s.append(latency)
                self.in_service_s.append(in_service)


@dataclass
class Phase:
    on: bool
    seconds: float
    service_cpu_s: float
    broker_cpu_s: float
    bench_cpu_s: float
    p99_s: dict[str, float]
    intervals: dict[str, int]
    published_messages: float = 0.0
    published_bytes: float = 0.0
    tick_s: float = 0.0
    """The edge node's own CPU time on the web loop (its counter)."""


def _sum(samples: dict[tuple[str, str], float], name: str) -> float:
    return sum(v for (metric, _), v in samples.items() if metric == name)


def _ready(base_url: str, names: list[str]) -> bool:
    import urllib.request

    for name in names:
        with urllib.request.urlopen(f"{base_url}/api/v1/robots/{name}/readyz", timeout=5) as r:
            if b'"ready":true' not in r.read():
                return False
    return True


def _scrape(base_url: str) -> dict[tuple[str, str], float]:
    import urllib.request

    with urllib.request.urlopen(base_url + "/metrics", timeout=5) as answer:
        return metrics(answer.read().decode())


def run_phase(
    args: argparse.Namespace,
    on: bool,
    *,
    cell: Cell,
    broker_url: str,
    broker_pid: int,
    subscription: Subscription,
    probe: mqtt.Client,
) -> Phase:
    names = cell.names
    extra = ["--mqtt-url", broker_url, "--sparkplug-node", "bench"] if on else []
    service, http_port = cell.serve(args.rpi_ms, *extra, log=f"service-{'on' if on else 'off'}.log")
    base_url = f"http://{cell.service_host}:{http_port}"
    try:
        _wait(lambda: _ready(base_url, names), "service", service, 60)
        time.sleep(args.settle_seconds)
        seconds = args.seconds / args.cycles
        before = _scrape(base_url)
        cpu0 = (process_cpu_s(service.pid), process_cpu_s(broker_pid), own_cpu_s())
        subscription.recording = on
        started = time.monotonic()
        while (left := started + seconds - time.monotonic()) > 0:
            if on:  # the baseline: the same path without the service
                probe.publish(PROBE_TOPIC, repr(time.time()).encode(), qos=0)
            time.sleep(min(left, PROBE_PERIOD_S))
        elapsed = time.monotonic() - started
        subscription.recording = False
        cpu1 = (process_cpu_s(service.pid), process_cpu_s(broker_pid), own_cpu_s())
        after = _scrape(base_url)
    finally:
        stop_process(service, 20)
    p99: dict[str, float] = {}
    counts: dict[str, int] = {}
    for name in names:
        p99[name], counts[name] = histogram_quantile(before, after, HISTOGRAM, 0.99, robot=name)
    phase = Phase(
        on,
        elapsed,
        cpu1[0] - cpu0[0],
        cpu1[1] - cpu0[1],
        cpu1[2] - cpu0[2],
        p99,
        counts,
    )
    if on:
        name = "cobot_hmi_sparkplug_messages_total"
        phase.published_messages = _sum(after, name) - _sum(before, name)
        name = "cobot_hmi_sparkplug_published_bytes_total"
        phase.published_bytes = _sum(after, name) - _sum(before, name)
        name = "cobot_hmi_sparkplug_tick_seconds_total"
        phase.tick_s = _sum(after, name) - _sum(before, name)
    return phase


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=4)
    parser.add_argument("--rpi-ms", type=float, default=10.0)
    parser.add_argument("--seconds", type=float, default=60.0, help="of each condition, in all")
    parser.add_argument("--cycles", type=int, default=3, help="off/on alternations")
    parser.add_argument("--settle-seconds", type=float, default=3.0)
    parser.add_argument(
        "--robot-niceness",
        type=int,
        default=-10,
        help="nice value of the emulators (a real robot is its own machine; 0: same as the rest)",
    )
    args = parser.parse_args()
    subscription = Subscription()
    phases: list[Phase] = []
    with (
        tempfile.TemporaryDirectory(prefix="cobot-bench-sparkplug-") as directory,
        emulated_cell(args.robots, Path(directory), robot_niceness=args.robot_niceness) as cell,
    ):
        state, service_host, names = cell.state, cell.service_host, cell.names
        with broker(service_host, state) as (broker_port, broker_process):
            client = mqtt.Client(CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv311)
            client.on_message = subscription.on_message
            client.on_connect = lambda c, *_: c.subscribe("spBv1.0/#", qos=0)
            client.connect(service_host, broker_port)
            client.loop_start()
            client.subscribe(PROBE_TOPIC, qos=0)
            probe = mqtt.Client(CallbackAPIVersion.VERSION2, protocol=mqtt.MQTTv311)
            probe.connect(service_host, broker_port)
            probe.loop_start()
            try:
                url = f"mqtt://{service_host}:{broker_port}"
                for _ in range(args.cycles):
                    for on in (False, True):
                        phases.append(
                            run_phase(
                                args,
                                on,
                                cell=cell,
                                broker_url=url,
                                broker_pid=broker_process.pid,
                                subscription=subscription,
                                probe=probe,
                            )
                        )
            finally:
                for each in (client, probe):
                    each.disconnect()
                    each.loop_stop()
    report(args, names, phases, subscription)
    return 0


def report(
    args: argparse.Namespace, names: list[str], phases: list[Phase], sub: Subscription
) -> None:
    on = [p for p in phases if p.on]
    off = [p for p in phases if not p.on]
    on_s = sum(p.seconds for p in on)
    off_s = sum(p.seconds for p in off)
    service_on = sum(p.service_cpu_s for p in on) / on_s * 100
    service_off = sum(p.service_cpu_s for p in off) / off_s * 100
    broker_on = sum(p.broker_cpu_s for p in on) / on_s * 100
    publisher = service_on - service_off
    ticks = sum(p.tick_s for p in on) / on_s * 100
    print(
        f"bench/sparkplug: {args.robots} robots at RPI {args.rpi_ms:g} ms; {args.cycles} "
        f"alternations of {args.seconds / args.cycles:g} s without and with the edge node "
        f"(default deadbands, at most 10 DDATA/s per robot); emulators at nice "
        f"{args.robot_niceness}; {os.cpu_count()} CPUs, load average "
        + ", ".join(f"{x:.2f}" for x in os.getloadavg())
    )
    published = sum(p.published_messages for p in on)
    published_bytes = sum(p.published_bytes for p in on)
    print(
        f"  published: {published / on_s:.1f} messages/s, {published_bytes / on_s:.0f} bytes/s "
        f"(payloads); received by the subscriber: {sub.messages / on_s:.1f} messages/s, "
        f"{sub.bytes / on_s:.0f} bytes/s"
    )
    print(
        f"  latency robot frame → subscriber ({len(sub.latencies_s)} DDATA): p50 "
        f"{percentile(sub.latencies_s, 0.5) * 1e3:.1f} ms, p99 "
        f"{percentile(sub.latencies_s, 0.99) * 1e3:.1f} ms (target ≤ 50 ms); of which in the "
        f"service (frame received → DDATA built) p50 {percentile(sub.in_service_s, 0.5) * 1e3:.1f}"
        f" ms, p99 {percentile(sub.in_service_s, 0.99) * 1e3:.1f} ms; the machine's own MQTT "
        f"path (this process → Mosquitto → this process, {len(sub.probe_s)} probes) p50 "
        f"{percentile(sub.probe_s, 0.5) * 1e3:.1f} ms, p99 "
        f"{percentile(sub.probe_s, 0.99) * 1e3:.1f} ms"
    )
    print(
        f"  service CPU: on {service_on:.1f} %, off {service_off:.1f} % of a core; the "
        f"publisher's share {publisher:.1f} % = {publisher / args.robots:.2f} % per robot "
        f"(target ≤ 5 %); the edge node's own CPU on the web loop {ticks:.2f} % = "
        f"{ticks / args.robots:.2f} % per robot (its counter; paho's network thread is in the "
        f"difference only); Mosquitto {broker_on:.1f} %"
    )
    ratios = []
    for name in names:
        p_on = statistics.median(p.p99_s[name] for p in on)
        p_off = statistics.median(p.p99_s[name] for p in off)
        ratio = p_on / p_off if p_off else float("nan")
        ratios.append(ratio)
        print(
            f"  robot {name}: cyclic receive interval p99 on {p_on * 1e3:.2f} ms, off "
            f"{p_off * 1e3:.2f} ms (median of the phases): ratio {ratio:.3f} (target ≤ 1.1); "
            f"per phase on "
            + ", ".join(f"{p.p99_s[name] * 1e3:.2f}" for p in on)
            + " / off "
            + ", ".join(f"{p.p99_s[name] * 1e3:.2f}" for p in off)
        )
    print(f"  worst ratio {max(ratios):.3f}")


if __name__ == "__main__":
    raise SystemExit(main())
