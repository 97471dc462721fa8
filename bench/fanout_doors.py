"""``bench/fanout --every-door`` (issue 40): the whole cell, every consumer of the frames open.

Beside the WebSocket clients of ``bench/fanout``: the recorder and the alarms (the service's
defaults), the cycle meter (the emulators run the demo program with its cycle marker, the
service's ``--cycle-trigger`` follows it), robot health (on by default), the Sparkplug B edge
node publishing to a local Mosquitto, and the OPC UA server with one asyncua client (a thread of
this process, ``bench/opcua``'s) subscribed to every variable of every robot. Printed after
``bench/fanout``'s figures: every consumer's dropped frames (each frame consumer's bounded queue,
``cobot_hmi_consumer_dropped_frames_total`` by consumer), the OPC UA client's notifications and
lost connections, and the targets of the whole cell: service CPU per robot-frame with clients
≤ 80 µs, every cyclic p99 ratio ≤ 1.05, 0 T→O gaps, 0 frames lost by any consumer that sees
every frame (the write confirmation keeps only the newest, ``NEWEST_ONLY``).
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from opcua_bench import Received, Subscriber
from service_bench_support import Stack, broker, free_port, labels_of, loopback_pair

CYCLE_MARKER_REGISTER = 63
"""The demo program's cycle-start marker (as ``cobot-hmi demo`` runs it)."""
EMULATOR_ARGS = ("--cycle-marker-register", str(CYCLE_MARKER_REGISTER))
NEWEST_ONLY = frozenset({"write-confirmation"})
"""Consumers that keep only the newest frames by design (a write waits for a frame after it;
``robots.confirmation``): their drops are printed, not counted as frames lost."""
TARGET_US = 80.0
TARGET_RATIO = 1.05


@dataclass
class Doors:
    """The broker and the OPC UA endpoint the service is told to use."""

    mqtt_url: str
    opcua_endpoint: str

    def service_args(self) -> tuple[str, ...]:
        return (
            "--cycle-trigger",
            f"bit_output_registers.{CYCLE_MARKER_REGISTER}:rising",
            "--mqtt-url",
            self.mqtt_url,
            "--sparkplug-node",
            "bench",
            "--opcua-url",
            self.opcua_endpoint,
        )


@contextlib.contextmanager
def doors() -> Iterator[Doors]:
    """A Mosquitto and an OPC UA address on loopback addresses of their own."""
    broker_host, opcua_host = loopback_pair()
    with (
        tempfile.TemporaryDirectory(prefix="cobot-bench-doors-") as directory,
        broker(broker_host, Path(directory)) as (broker_port, _),
    ):
        endpoint = f"opc.tcp://{opcua_host}:{free_port(opcua_host)}"
        yield Doors(f"mqtt://{broker_host}:{broker_port}", endpoint)


@contextlib.contextmanager
def opcua_client(doors: Doors, running: Stack) -> Iterator[tuple[Subscriber, Received]]:
    """One client subscribed to every variable of every robot until the end."""
    received = Received()
    received.recording = True
    subscriber = Subscriber(doors.opcua_endpoint, list(running.robot_names), received)
    try:
        subscriber.start()
        yield subscriber, received
    finally:
        subscriber.stop()
        subscriber.close()


def consumer_drops(final: dict[tuple[str, str], float]) -> dict[str, float]:
    """Every frame consumer's dropped frames, summed over the robots."""
    drops: dict[str, float] = {}
    for (metric, labels), value in final.items():
        if metric == "cobot_hmi_consumer_dropped_frames_total":
            consumer = labels_of(labels).get("consumer", "?")
            drops[consumer] = drops.get(consumer, 0.0) + value
    return drops


def report(
    final: dict[tuple[str, str], float],
    subscriber: Subscriber,
    received: Received,
    service_us: float,
    ratios: dict[str, float],
) -> bool:
    """The doors' figures and the whole cell's targets; whether every one was met."""
    drops = consumer_drops(final)
    listed = ", ".join(f"{name} {count:.0f}" for name, count in sorted(drops.items()))
    print(f"  every door: frames dropped by each consumer: {listed or 'no consumer listed'}")
    print(
        f"  OPC UA client: {subscriber.variables} variables subscribed, "
        f"{received.notifications} notifications, {received.connections_lost} connection(s) lost"
    )
    gaps = sum(v for (m, _), v in final.items() if m == "cobot_hmi_frame_gaps_total")
    worst = max(ratios.values(), default=float("nan"))
    met = (
        service_us <= TARGET_US
        and worst <= TARGET_RATIO
        and gaps == 0
        and not any(count for name, count in drops.items() if name not in NEWEST_ONLY)
        and received.connections_lost == 0
    )
    print(
        f"  whole cell targets (≤ {TARGET_US:g} µs per robot-frame with clients, every ratio "
        f"≤ {TARGET_RATIO}, 0 gaps, 0 frames dropped by any consumer): {met} "
        f"({service_us:.1f} µs, worst ratio {worst:.3f}, {gaps:.0f} gaps)"
    )
    return met
