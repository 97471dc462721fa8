"""Benchmark of issue 41 (``bench/plant``): the plant as a Sparkplug host application under a
plant's load.

``--cells`` (50) simulated cells of ``--robots`` (10) robots each publish as our edge node does
(bench/plant_load.py: a recording of the real edge node over one emulated robot, replayed with
the edge node's own encoder at its own rate) to a local broker, and ``cobot-hmi plant``
(bench/plant_host.py: the verb's runtime and web app in its own process, with a hook that times
each DDATA into the model) consumes them for ``--minutes`` (5), while this process polls its REST
API as the plant page does (the nodes every 250 ms, the alarms every second).

Printed: message → page model latency p50/p99 (the DDATA's payload timestamp, set when it was
built, to the host having applied it; targets p99 ≤ 1 s); the plant's CPU in cores (≤ 1); its
resident memory at the start and the end of the measured window (the medians of its first and
last 30 s, sampled every second; flat: ± 5 %); the seq gaps the host saw, the rebirths it asked
for, the gaps still unanswered at the end (a node whose births have not come since its gap:
target 0) and the requests the cells received and answered; the plant's inbox at its fullest;
messages published and received; the page's answers' times; the broker's and this process's
CPU; the load average.

``--kill-broker``: the broker is a cluster of three ``nats-server`` nodes (MQTT on JetStream,
``make peers`` builds ``.venv/go-bin/nats-server``), the cells on the first node, the plant
given the second and the third; the plant's node is killed (SIGKILL) half-way: the plant moves
to the third, asks for rebirths on the gaps, and every cell and robot must be online again.

Run by hand: bench/plant [--minutes 5] [--cells 50] [--robots 10] [--kill-broker]
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from plant_load import LoadGenerator, Template, record_template
from proc_stats import load_average, own_cpu_s, process_cpu_s, rss_mib
from service_bench_support import Mosquitto, _wait, free_port, loopback_cell, stop_process

HERE: Final = Path(__file__).resolve().parent
REPO: Final = HERE.parent
NATS_SERVER: Final = REPO / ".venv" / "go-bin" / "nats-server"
NODES_POLL_S: Final = 0.25
ALARMS_POLL_S: Final = 1.0
RSS_SPAN: Final = 30
"""Samples (about a second apart) whose median is the resident memory at the window's start
and at its end."""


@dataclass
class PagePoller:
    """The plant page's requests, from a thread: how long each answer took."""

    base_url: str
    nodes_s: list[float] = field(default_factory=list)
    alarms_s: list[float] = field(default_factory=list)
    errors: int = 0
    stopping: threading.Event = field(default_factory=threading.Event)

    def run(self) -> None:
        next_alarms = 0.0
        while not self.stopping.wait(NODES_POLL_S):
            self._get("/api/v1/plant/nodes", self.nodes_s)
            if time.monotonic() >= next_alarms:
                next_alarms = time.monotonic() + ALARMS_POLL_S
                self._get("/api/v1/plant/alarms?limit=200", self.alarms_s)

    def _get(self, path: str, times: list[float]) -> None:
        started = time.monotonic()
        try:
            with urllib.request.urlopen(self.base_url + path, timeout=10) as answer:
                answer.read()
        except OSError:
            self.errors += 1
            return
        times.append(time.monotonic() - started)


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


def histogram_percentile(bins: dict[str, int], bin_s: float, q: float) -> float:
    total = sum(bins.values())
    seen = 0
    for index in sorted(bins, key=int):
        seen += bins[index]
        if seen >= q * total:
            return (int(index) + 1) * bin_s
    return float("nan")


# ---------------------------------------------------------------- brokers


class NatsCluster:
    """Three clustered ``nats-server`` nodes with MQTT (as tests/test_plant_nats_cluster.py)."""

    def __init__(self, hosts: list[str], directory: Path) -> None:
        if not NATS_SERVER.exists():
            raise SystemExit(f"--kill-broker needs {NATS_SERVER} (make peers)")
        cluster_ports = [free_port(h) for h in hosts]
        routes = ", ".join(
            f"nats-route://{h}:{p}" for h, p in zip(hosts, cluster_ports, strict=True)
        )
        self.urls: list[tuple[str, int]] = []
        self.processes: list[subprocess.Popen[bytes]] = []
        for index, host in enumerate(hosts):
            name = f"n{index + 1}"
            mqtt_port = free_port(host)
            config = directory / f"{name}.conf"
            config.write_text(
                f"server_name: {name}\nlisten: {host}:{free_port(host)}\n"
                f'jetstream {{ store_dir: "{directory / name}" }}\n'
                f"cluster {{ name: plant, listen: {host}:{cluster_ports[index]}, "
                f"routes: [{routes}] }}\nmqtt {{ listen: {host}:{mqtt_port} }}\n"
            )
            self.urls.append((host, mqtt_port))
            self.processes.append(
                subprocess.Popen(
                    [str(NATS_SERVER), "-c", str(config)],
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            )
        for (host, port), process in zip(self.urls, self.processes, strict=True):
            _wait(functools.partial(_mqtt_accepts, host, port), "nats-server", process, 60)

    def kill(self, index: int) -> None:
        self.processes[index].send_signal(signal.SIGKILL)
        self.processes[index].wait()

    def stop(self) -> None:
        for process in self.processes:
            stop_process(process, sig=signal.SIGTERM)


def _mqtt_accepts(host: str, port: int) -> bool:
    """A CONNECT answered with a CONNACK accepting it (NATS refuses until its JetStream is up)."""
    import socket

    connect = bytes.fromhex("101000044d5154540402003c0004") + b"wait"
    try:
        with socket.create_connection((host, port), timeout=2) as sock:
            sock.sendall(connect)
            sock.settimeout(5)
            answer = sock.recv(4)
    except OSError:
        return False
    return answer[:1] == b"\x20" and answer[3:4] == b"\x00"


# ---------------------------------------------------------------- the run


@dataclass
class Window:
    """What was measured between the end of the settling and the end of the run."""

    seconds: float = 0.0
    plant_cpu_s: float = 0.0
    broker_cpu_s: float = 0.0
    bench_cpu_s: float = 0.0
    rss_start_mib: float = 0.0
    rss_end_mib: float = 0.0
    rss_samples_mib: list[float] = field(default_factory=list)
    """The plant's resident memory about every second of the window."""
    sent: int = 0
    published: int = 0
    killed_at_s: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)


def start_plant(
    urls: list[str], host: str, directory: Path, stats: Path
) -> tuple[subprocess.Popen[bytes], str]:
    port = free_port(host)
    flags = [part for url in urls for part in ("--mqtt-url", url)]
    command = [sys.executable, str(HERE / "plant_host.py"), *flags]
    command += ["--host", host, "--port", str(port), "--state-dir", str(directory)]
    command += ["--stats", str(stats)]
    log = (directory.parent / "plant.log").open("wb")
    process = subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT)
    base_url = f"http://{host}:{port}"

    def up() -> bool:
        try:
            with urllib.request.urlopen(base_url + "/healthz", timeout=2) as answer:
                return bool(answer.status == 200)
        except OSError:
            return False

    _wait(up, "the plant", process, 60)
    return process, base_url


def measure(
    args: argparse.Namespace,
    generator: LoadGenerator,
    *,
    plant: subprocess.Popen[bytes],
    broker_pids: list[int],
    stats: Path,
    kill: Any,
) -> Window:
    """Settle (every cell born, the plant caught up), reset the plant's latencies, then measure."""
    time.sleep(args.settle_seconds)
    stats.with_suffix(".reset").touch()
    window = Window()
    cpu0 = (process_cpu_s(plant.pid), sum(process_cpu_s(p) for p in broker_pids), own_cpu_s())
    sent0, published0 = generator.sent, sum(c.published for c in generator.cells)
    started = time.monotonic()
    seconds = args.minutes * 60
    while (left := started + seconds - time.monotonic()) > 0:
        if kill is not None and window.killed_at_s is None and left <= seconds / 2:
            window.killed_at_s = time.monotonic() - started
            kill()
        window.rss_samples_mib.append(rss_mib(plant.pid))
        time.sleep(min(left, 1.0))
    window.seconds = time.monotonic() - started
    window.plant_cpu_s = process_cpu_s(plant.pid) - cpu0[0]
    window.broker_cpu_s = (
        sum(process_cpu_s(p) for p in broker_pids if _alive(p)) - cpu0[1]
        if kill is None
        else float("nan")
    )
    window.bench_cpu_s = own_cpu_s() - cpu0[2]
    # Start and end: the medians of the window's first and last RSS_SPAN samples (a second's
    # sample catches a flush's Arrow buffers or a full inbox at their largest; a trend shows in
    # the medians as it does in single samples).
    span = max(1, min(RSS_SPAN, len(window.rss_samples_mib) // 4))
    window.rss_start_mib = percentile(window.rss_samples_mib[:span], 0.5)
    window.rss_end_mib = percentile(window.rss_samples_mib[-span:], 0.5)
    window.extra["stats_at_end"] = json.loads(stats.read_text()) if stats.exists() else {}
    window.sent = generator.sent - sent0
    window.published = sum(c.published for c in generator.cells) - published0
    return window


def _alive(pid: int) -> bool:
    return Path(f"/proc/{pid}").exists()


def run(args: argparse.Namespace, directory: Path) -> None:
    hosts, bench_host = loopback_cell(3)
    cluster: NatsCluster | None = None
    mosquitto: Mosquitto | None = None
    calibration = Mosquitto(hosts[0], directory)
    calibration.start()
    try:
        print("recording the real edge node (one emulated robot) …", flush=True)
        template = record_template(args.calibrate_seconds, args.rpi_ms, hosts[0], calibration.port)
    finally:
        calibration.stop()
    if args.kill_broker:
        (directory / "nats").mkdir()
        cluster = NatsCluster(hosts, directory / "nats")
        cells_at = cluster.urls[0]
        plant_urls = [f"mqtt://{h}:{p}" for h, p in cluster.urls[1:]]
        broker_pids = [p.pid for p in cluster.processes]
    else:
        mosquitto = Mosquitto(hosts[0], directory)
        mosquitto.start()
        assert mosquitto.process is not None
        cells_at = (hosts[0], mosquitto.port)
        plant_urls = [mosquitto.url]
        broker_pids = [mosquitto.process.pid]
    stats = directory / "plant-stats.json"
    (directory / "plant").mkdir()
    plant, base_url = start_plant(plant_urls, bench_host, directory / "plant", stats)
    generator = LoadGenerator(args.cells, args.robots, template, cells_at)
    poller = PagePoller(base_url)
    poll_thread = threading.Thread(target=poller.run, name="page", daemon=True)
    kill = (lambda: cluster.kill(1)) if cluster is not None else None
    try:
        generator.start()
        poll_thread.start()
        window = measure(
            args, generator, plant=plant, broker_pids=broker_pids, stats=stats, kill=kill
        )
        # The last rebirths answered before the counts are read.
        time.sleep(args.settle_seconds / 2)
    finally:
        poller.stopping.set()
        generator.stop()
        stop_process(plant, 30)
        if cluster is not None:
            cluster.stop()
        if mosquitto is not None:
            mosquitto.stop()
    figures = json.loads(stats.read_text()) if stats.exists() else {}
    if not figures.get("stopped"):  # killed before its last word: its figures at the window's end
        figures = window.extra.get("stats_at_end", figures)
    report(args, template, window=window, generator=generator, poller=poller, figures=figures)


def report(
    args: argparse.Namespace,
    template: Template,
    *,
    window: Window,
    generator: LoadGenerator,
    poller: PagePoller,
    figures: dict[str, Any],
) -> None:
    robots = args.cells * args.robots
    print(
        f"bench/plant: {args.cells} cells × {args.robots} robots = {robots} robots, "
        f"{window.seconds / 60:.1f} min measured after {args.settle_seconds:g} s of settling"
        + (
            f"; the plant's broker node killed at {window.killed_at_s:.0f} s (3-node NATS)"
            if window.killed_at_s is not None
            else " (Mosquitto)"
        )
        + f"; {os.cpu_count()} CPUs, load average {load_average()}"
    )
    print(
        f"  the edge node's real rate (recorded over one emulated robot, "
        f"{args.calibrate_seconds:g} s): {template.rate_hz:.1f} DDATA/s per robot, "
        f"{template.metrics_per_message:.1f} metrics each; the plant's load "
        f"{template.rate_hz * robots:.0f} DDATA/s"
    )
    lag = generator.lag_s
    print(
        f"  published {window.published / window.seconds:.0f} messages/s (DDATA "
        f"{window.sent / window.seconds:.0f}/s; the generator's lag p99 "
        f"{percentile(lag, 0.99) * 1e3:.0f} ms); the plant received {figures.get('messages', 0)}"
        f" messages in all ({figures.get('bad_messages', '?')} bad)"
    )
    bins, bin_s = figures.get("latency_bins", {}), figures.get("latency_bin_s", 0.0005)
    p50, p99 = (histogram_percentile(bins, bin_s, q) for q in (0.5, 0.99))
    print(
        f"  message → page model ({figures.get('latency_count', 0)} DDATA): p50 {p50 * 1e3:.1f} ms,"
        f" p99 {p99 * 1e3:.1f} ms (target ≤ 1000 ms); max "
        f"{histogram_percentile(bins, bin_s, 1.0) * 1e3:.0f} ms"
    )
    cores = window.plant_cpu_s / window.seconds
    rss_max = max(window.rss_samples_mib, default=0.0)
    change = (window.rss_end_mib / window.rss_start_mib - 1) * 100 if window.rss_start_mib else 0
    print(
        f"  the plant: {cores:.2f} cores (target ≤ 1); resident memory {window.rss_start_mib:.0f}"
        f" MiB → {window.rss_end_mib:.0f} MiB ({change:+.1f} %, target ± 5 %; medians of the "
        f"window's first and last {RSS_SPAN} s, at most {rss_max:.0f} MiB)"
        f"; history rows "
        f"{figures.get('history_rows', '?')}; broker CPU {window.broker_cpu_s / window.seconds:.2f}"
        f" cores; this process (load and page) {window.bench_cpu_s / window.seconds:.2f} cores"
    )
    rebirths = figures.get("rebirths", {})
    asked = sum(rebirths.values())
    print(
        f"  seq gaps and rebirths: the plant asked {asked} ({rebirths or 'none'}; "
        f"{figures.get('rebirths_held', 0)} held by its rate limit); gaps unanswered at the end "
        f"{figures.get('unanswered', '?')} (nodes whose births did not come since: a request "
        f"held or not answered; target 0); the cells received {generator.rebirths_asked} "
        f"requests ({max(asked - generator.rebirths_asked, 0)} lost on the way) and answered "
        f"with {generator.births_sent - args.cells} births; at the end "
        f"{figures.get('nodes_online', '?')}/{args.cells} cells and "
        f"{figures.get('devices_online', '?')}/{robots} robots online; connections "
        f"{figures.get('connections', '?')} ({figures.get('connections_lost', '?')} lost)"
    )
    killed = "" if figures.get("stopped") else "; it did not stop within 30 s: killed"
    print(
        f"  the plant's event loop behind by {figures.get('loop_lag_s', float('nan')):.1f} s at "
        f"the end; {figures.get('gc_full', '?')} full garbage collections (the longest "
        f"{figures.get('gc_full_longest_s', float('nan')) * 1e3:.0f} ms); its inbox (received, "
        f"not yet handled) at most {figures.get('inbox_max', '?')}"
        f" messages, full {figures.get('inbox_full', '?')} times (the client's thread waited: "
        f"the broker held or dropped for it){killed}"
    )

    print(
        f"  the page's requests: nodes p50 {percentile(poller.nodes_s, 0.5) * 1e3:.0f} ms, p99 "
        f"{percentile(poller.nodes_s, 0.99) * 1e3:.0f} ms ({len(poller.nodes_s)}); alarms p99 "
        f"{percentile(poller.alarms_s, 0.99) * 1e3:.0f} ms; {poller.errors} failed"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=5.0, help="measured, after settling")
    parser.add_argument("--cells", type=int, default=50)
    parser.add_argument("--robots", type=int, default=10, help="per cell")
    parser.add_argument("--kill-broker", action="store_true")
    parser.add_argument("--settle-seconds", type=float, default=20.0)
    parser.add_argument("--calibrate-seconds", type=float, default=20.0)
    parser.add_argument("--rpi-ms", type=float, default=10.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="cobot-bench-plant-") as directory:
        run(args, Path(directory))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
