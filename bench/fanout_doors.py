"""``bench/fanout --every-door`` (issue 40): the whole cell, every consumer of the frames open.

Beside the WebSocket clients of ``bench/fanout``: the recorder and the alarms (the service's
defaults), the cycle meter (the emulators run the demo program with its cycle marker, the
service's ``--cycle-trigger`` follows it), robot health (on by default), the Sparkplug B edge
node publishing to a local Mosquitto, and the OPC UA server with one asyncua client subscribed
to every variable of every robot as a historian does (``fanout_historian``: a process of its
own, every second, batched). Printed after ``bench/fanout``'s figures: every consumer's dropped
frames (each frame consumer's bounded queue, ``cobot_hmi_consumer_dropped_frames_total`` by
consumer), the historian's notifications, latency, lost connections and missing notification
messages, and each target of the whole cell beside its figure: service CPU per robot-frame with
clients ≤ 80 µs, every cyclic p99 ratio ≤ 1.05, 0 T→O gaps, 0 frames lost by any consumer that
sees every frame (the write confirmation keeps only the newest, ``NEWEST_ONLY``) nor by a
WebSocket client, the historian's session kept whole.
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import orjson
from proc_stats import CLOCK_TICKS
from service_bench_support import Stack, broker, free_port, labels_of, loopback_pair

CYCLE_MARKER_REGISTER = 63
"""The demo program's cycle-start marker (as ``cobot-hmi demo`` runs it)."""
EMULATOR_ARGS = ("--cycle-marker-register", str(CYCLE_MARKER_REGISTER))
NEWEST_ONLY = frozenset({"write-confirmation"})
"""Consumers that keep only the newest frames by design (a write waits for a frame after it;
``robots.confirmation``): their drops are printed, not counted as frames lost."""
HISTORIAN_INTERVAL_MS = 1000.0
"""The historian's publishing and sampling interval (``fanout_historian``)."""
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


@dataclass
class Historian:
    """The OPC UA client (``fanout_historian``, a process of its own) and, once finished, what
    it saw."""

    process: subprocess.Popen[str]
    variables: int
    seen: dict[str, Any] = field(default_factory=dict)

    def finish(self) -> dict[str, Any]:
        """Its figures (its standard input closed: it disconnects and prints them)."""
        if not self.seen and self.process.poll() is None:
            assert self.process.stdin is not None and self.process.stdout is not None
            self.process.stdin.close()
            line = self.process.stdout.readline()
            self.seen = orjson.loads(line) if line.startswith("{") else {"error": line.strip()}
        return self.seen


@contextlib.contextmanager
def opcua_client(
    doors: Doors, running: Stack, interval_ms: float = HISTORIAN_INTERVAL_MS
) -> Iterator[Historian]:
    """One historian subscribed to every variable of every robot until the end."""
    process = subprocess.Popen(
        [
            sys.executable,
            str(Path(__file__).with_name("fanout_historian.py")),
            doors.opcua_endpoint,
            ",".join(running.robot_names),
            "--interval-ms",
            str(interval_ms),
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        line = process.stdout.readline()  # ``ready N`` once subscribed (minutes at 32 robots)
        if not line.startswith("ready "):
            raise SystemExit(f"the OPC UA historian did not subscribe: {line!r}")
        historian = Historian(process, int(line.split()[1]))
        yield historian
        historian.finish()
    finally:
        if process.poll() is None:
            process.terminate()
        process.wait(30)


def thread_cpu_s(pid: int) -> dict[str, float]:
    """CPU seconds of each of a process's threads so far, summed by thread name (from /proc:
    the service's cyclic thread, web loop, OPC UA server, paho, health, recorder …)."""
    by_name: dict[str, float] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(OSError):  # a thread that ended meanwhile
            name = (task / "comm").read_text().strip()
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
            seconds = (int(fields[11]) + int(fields[12])) / CLOCK_TICKS
            by_name[name] = by_name.get(name, 0.0) + seconds
    return by_name


def report_threads(before: dict[str, float], after: dict[str, float], frames: int) -> None:
    """The service's CPU per robot-frame by thread over the whole run (both conditions)."""
    spent = {name: after[name] - before.get(name, 0.0) for name in after}
    ranked = sorted(spent.items(), key=lambda item: -item[1])
    print(
        "  service CPU per robot-frame by thread, the whole run ("
        f"{frames} frames): "
        + ", ".join(f"{name} {1e6 * s / max(frames, 1):.1f} µs" for name, s in ranked if s > 0)
    )


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
    initial: dict[tuple[str, str], float],
    historian: Historian,
    *,
    service_us: float,
    ratios: dict[str, float],
    clients_lossless: bool,
) -> bool:
    """The doors' figures and the whole cell's targets beside them; whether every one was met."""
    drops = consumer_drops(final)
    print("  every door: frames dropped by each consumer (target 0; newest-only ones printed):")
    for name, count in sorted(drops.items()):
        rule = "newest only by design, not counted" if name in NEWEST_ONLY else "target 0"
        print(f"    {name}: {count:.0f} ({rule})")
    if not drops:
        print("    no consumer listed")
    lost = sum(count for name, count in drops.items() if name not in NEWEST_ONLY)
    seen = historian.finish()
    p50, p99 = seen.get("latency_p50_s"), seen.get("latency_p99_s")
    latency = f"p50 {p50 * 1e3:.0f} ms, p99 {p99 * 1e3:.0f} ms" if p50 and p99 else "none"
    print(
        f"  OPC UA historian (every {HISTORIAN_INTERVAL_MS:g} ms, queue 1): "
        f"{seen.get('variables', historian.variables)} variables, "
        f"{seen.get('notifications', 0)} notifications while measured, latency {latency}; "
        f"connections lost {seen.get('connections_lost', '?')}, notification messages missing "
        f"{seen.get('sequence_gaps', '?')}, status changes {seen.get('status_changes', '?')}"
        + (f"; {seen['error']}" if "error" in seen else "")
    )
    historian_ok = (
        seen.get("connections_lost") == 0
        and seen.get("sequence_gaps") == 0
        and not seen.get("status_changes")
        and bool(seen.get("notifications"))
    )

    def total_gaps(samples: dict[tuple[str, str], float]) -> float:
        return sum(v for (m, _), v in samples.items() if m == "cobot_hmi_frame_gaps_total")

    # While measured: the service's start (its OPC UA address space built while the robots
    # already send) is not the cell at work.
    gaps = total_gaps(final) - total_gaps(initial)
    print(f"  T→O gaps since the service started: {total_gaps(final):.0f}")
    worst = max(ratios.values(), default=float("nan"))
    checks = [
        (
            "service CPU per robot-frame with clients",
            f"{service_us:.1f} µs",
            f"≤ {TARGET_US:g} µs",
            service_us <= TARGET_US,
        ),
        ("worst cyclic p99 ratio", f"{worst:.3f}", f"≤ {TARGET_RATIO}", worst <= TARGET_RATIO),
        ("T→O gaps while measured", f"{gaps:.0f}", "0", gaps == 0),
        ("frames lost by the consumers", f"{lost:.0f}", "0", lost == 0),
        (
            "frames lost by the WebSocket clients",
            "0" if clients_lossless else "some",
            "0",
            clients_lossless,
        ),
        (
            "OPC UA historian whole (session kept, no message missing)",
            str(historian_ok),
            "True",
            historian_ok,
        ),
    ]
    print("  whole cell, measured against its target:")
    for label, measured, target, ok in checks:
        print(f"    {label}: {measured} (target {target}): {'met' if ok else 'NOT met'}")
    met = all(ok for *_, ok in checks)
    print(f"  whole cell targets met: {met}")
    return met
