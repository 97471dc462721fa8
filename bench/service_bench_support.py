"""Shared by ``bench/fanout`` and ``bench/write_latency``: the emulators (one per robot) and the
service as their own processes on fresh loopback addresses, Prometheus parsing (per robot).

Never a fixed address: each run picks 127.<random>.<random>.x pairs, so a bench can run next to
tests and other benches on the same machine.
"""

from __future__ import annotations

import functools
import os
import random
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from cobot_hmi.service.access.users import Role, UsersFile

BENCH_USER = ("bench", "bench-password")


def free_port(host: str, kind: int = socket.SOCK_STREAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


def loopback_pair() -> tuple[str, str]:
    """Two fresh loopback addresses: the robot's and the service's."""
    robots, service = loopback_cell(1)
    return robots[0], service


def loopback_cell(robots: int) -> tuple[list[str], str]:
    """Fresh loopback addresses: one per robot, and the service's."""
    a, b = random.randint(100, 250), random.randint(0, 250)
    return [f"127.{a}.{b}.{10 + i}" for i in range(robots)], f"127.{a}.{b}.3"


@dataclass
class Stack:
    robot_hosts: list[str]
    robot_names: list[str]
    service_host: str
    http_port: int
    emulators: list[subprocess.Popen[bytes]]
    service: subprocess.Popen[bytes]
    state_dir: Path

    @property
    def robot_host(self) -> str:
        return self.robot_hosts[0]

    @property
    def emulator(self) -> subprocess.Popen[bytes]:
        return self.emulators[0]

    @property
    def base_url(self) -> str:
        return f"http://{self.service_host}:{self.http_port}"

    @property
    def ws_url(self) -> str:
        """The first robot's stream."""
        return self.robot_ws_url(self.robot_names[0])

    def robot_ws_url(self, name: str) -> str:
        return f"ws://{self.service_host}:{self.http_port}/api/v1/robots/{name}/stream"

    def get(self, path: str) -> bytes:
        # 30 s: a service with many robots and clients on a busy machine answers late, not never
        with urllib.request.urlopen(self.base_url + path, timeout=30) as answer:
            data: bytes = answer.read()
            return data


def _cli(
    *args: str, log: Path, niceness: int = 0, source: Path | None = None
) -> subprocess.Popen[bytes]:
    """``cobot-hmi ARGS`` as a child; ``source``: run the package found there (another
    commit's ``backend/src``, its extension built in place) instead of this one."""
    # ``nice`` before exec: every thread of the process inherits it (GNU nice still runs the
    # command, with a warning in the log, where raising the priority is not permitted).
    prefix = ["nice", "-n", str(niceness)] if niceness else []
    env = None if source is None else {**os.environ, "PYTHONPATH": str(source)}
    with log.open("wb") as out:
        return subprocess.Popen(
            [*prefix, sys.executable, "-m", "cobot_hmi.cli", *args],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
        )


def stop_process(
    process: subprocess.Popen[bytes] | None, timeout_s: float = 10.0, sig: int = signal.SIGINT
) -> None:
    """Stop a child (SIGINT by default: a clean stop, the service's Forward Closes), killed
    if it is not gone within ``timeout_s``. Nothing for one that is not running."""
    if process is None or process.poll() is not None:
        return
    process.send_signal(sig)
    try:
        process.wait(timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def _wait(
    check: Callable[[], bool],
    what: str,
    process: subprocess.Popen[bytes],
    timeout_s: float,
    interval_s: float = 0.1,
) -> None:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if process.poll() is not None:
            raise SystemExit(f"{what}: the process exited ({process.returncode})")
        try:
            if check():
                return
        except OSError:
            pass
        time.sleep(interval_s)
    raise SystemExit(f"{what}: not ready within {timeout_s:.0f} s")


def _accepts(host: str, port: int) -> bool:
    with socket.create_connection((host, port), 0.5):
        return True


def _ready(running: Stack) -> bool:
    return all(
        b'"ready":true' in running.get(f"/api/v1/robots/{name}/readyz")
        for name in running.robot_names
    )


@dataclass
class Cell:
    """The robots of a bench's cell: one emulator process each, named r1, r2, … in a
    ``[[robots]]`` TOML file (``config``) the service reads with ``--config``."""

    names: list[str]
    robot_hosts: list[str]
    service_host: str
    state: Path
    config: Path
    emulators: list[subprocess.Popen[bytes]]

    def serve(
        self, rpi_ms: float, *service_args: str, log: str, source: Path | None = None
    ) -> tuple[subprocess.Popen[bytes], int]:
        """The service of this cell (``cobot-hmi serve``: its web side on the service's address,
        a fresh port), logging to ``log`` in the state directory: the process and its HTTP
        port. ``source``: the service of another commit (``_cli``)."""
        http_port = free_port(self.service_host)
        process = _cli(
            "serve",
            "--config",
            str(self.config),
            "--local-host",
            self.service_host,
            "--host",
            self.service_host,
            "--port",
            str(http_port),
            "--rpi-ms",
            str(rpi_ms),
            "--state-dir",
            str(self.state),
            *service_args,
            log=self.state / log,
            source=source,
        )
        return process, http_port


@contextmanager
def emulated_cell(
    robots: int, state: Path, *, robot_niceness: int = 0, emulator_args: tuple[str, ...] = ()
) -> Iterator[Cell]:
    """``robots`` emulators on fresh loopback addresses (each its own process, accepting before
    this yields, stopped at the end), their ``[[robots]]`` file and the bench's operator user in
    the state directory ``state``; ``emulator_args`` go to every emulator's command line."""
    robot_hosts, service_host = loopback_cell(robots)
    names = [f"r{i + 1}" for i in range(robots)]
    tcp_ports = [free_port(host) for host in robot_hosts]
    UsersFile(state / "users.json").add(BENCH_USER[0], Role.OPERATOR, BENCH_USER[1])
    config = state / "cell.toml"
    config.write_text(
        "".join(
            f'[[robots]]\nname = "{name}"\nhost = "{host}"\ntcp_port = {port}\n'
            for name, host, port in zip(names, robot_hosts, tcp_ports, strict=True)
        ),
        encoding="utf-8",
    )
    emulators: list[subprocess.Popen[bytes]] = []
    try:
        for index, (host, port) in enumerate(zip(robot_hosts, tcp_ports, strict=True)):
            emulators.append(
                _cli(
                    "emulator",
                    "--host",
                    host,
                    "--tcp-port",
                    str(port),
                    "--control-port",
                    "0",
                    "--seed",
                    str(index + 1),
                    *emulator_args,
                    log=state / f"emulator-{index + 1}.log",
                    niceness=robot_niceness,
                )
            )
        for host, port, emulator in zip(robot_hosts, tcp_ports, emulators, strict=True):
            _wait(functools.partial(_accepts, host, port), "emulator", emulator, 120)
        yield Cell(names, robot_hosts, service_host, state, config, emulators)
    finally:
        for process in emulators:
            stop_process(process)


@contextmanager
def serving(
    cell: Cell, rpi_ms: float, *service_args: str, log: str, source: Path | None = None
) -> Iterator[Stack]:
    """The service of ``cell`` (``Cell.serve``), once every robot is ready; stopped (SIGINT)
    at the end. Several in a row on one cell compare services on the same robots."""
    service: subprocess.Popen[bytes] | None = None
    try:
        service, http_port = cell.serve(rpi_ms, *service_args, log=log, source=source)
        running = Stack(
            cell.robot_hosts,
            cell.names,
            cell.service_host,
            http_port,
            cell.emulators,
            service,
            cell.state,
        )
        _wait(lambda: _ready(running), "service", service, 240)
        yield running
    finally:
        stop_process(service)


@contextmanager
def stack(
    rpi_ms: float,
    *service_args: str,
    robot_niceness: int = 0,
    robots: int = 1,
    service_source: Path | None = None,
    emulator_args: tuple[str, ...] = (),
) -> Iterator[Stack]:
    """``robots`` emulators and the service holding a connection to each, every one its own
    process; stopped (SIGINT) at the end. The robots are ``[[robots]]`` of a TOML file.

    ``robot_niceness`` below 0 runs the emulators at a higher priority: a real robot is its own
    machine, whose frame timing does not suffer from this host's other processes.
    ``service_source``: the service of another commit (``_cli``); the emulators stay this one.
    ``emulator_args``: given to every emulator (``emulated_cell``).
    """
    with (
        tempfile.TemporaryDirectory(prefix="cobot-bench-") as directory,
        emulated_cell(
            robots, Path(directory), robot_niceness=robot_niceness, emulator_args=emulator_args
        ) as cell,
        serving(cell, rpi_ms, *service_args, log="service.log", source=service_source) as running,
    ):
        yield running


class Mosquitto:
    """Debian's ``mosquitto`` on ``host`` (a fresh port unless given), no persistence; it can be
    stopped and started again on the same port (a broker restart)."""

    def __init__(self, host: str, directory: Path, port: int | None = None) -> None:
        binary = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
        if not os.access(binary, os.X_OK):
            raise SystemExit("this bench needs Debian's mosquitto (apt-get install mosquitto)")
        self.host = host
        self.port = port or free_port(host)
        self.config = directory / "mosquitto.conf"
        self.config.write_text(
            f"listener {self.port} {host}\nallow_anonymous true\npersistence false\nlog_dest none\n"
        )
        self.binary = binary
        self.process: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"mqtt://{self.host}:{self.port}"

    def start(self, interval_s: float = 0.1) -> None:
        """Start it and return once it accepts connections."""
        self.process = subprocess.Popen([self.binary, "-c", str(self.config)])
        _wait(
            functools.partial(_accepts, self.host, self.port),
            "mosquitto",
            self.process,
            15,
            interval_s,
        )

    def stop(self) -> None:
        stop_process(self.process, sig=signal.SIGTERM)


@contextmanager
def broker(host: str, directory: Path) -> Iterator[tuple[int, subprocess.Popen[bytes]]]:
    """A Mosquitto on a fresh port of ``host``: (its port, its process); stopped at the end."""
    mosquitto = Mosquitto(host, directory)
    try:
        mosquitto.start()
        assert mosquitto.process is not None
        yield mosquitto.port, mosquitto.process
    finally:
        mosquitto.stop()


_SAMPLE = re.compile(r"^(?P<name>[a-z_]+)(?:\{(?P<labels>[^}]*)\})? (?P<value>\S+)$")


def metrics(text: str) -> dict[tuple[str, str], float]:
    """Prometheus text → {(name, labels): value}."""
    out: dict[tuple[str, str], float] = {}
    for line in text.splitlines():
        match = _SAMPLE.match(line)
        if match:
            out[(match["name"], match["labels"] or "")] = float(match["value"])
    return out


def labels_of(text: str) -> dict[str, str]:
    """``a="x",b="y"`` → {"a": "x", "b": "y"} (the values this service writes hold no quotes)."""
    return dict(re.findall(r'([a-z_]+)="([^"]*)"', text))


def value_of(samples: dict[tuple[str, str], float], name: str, robot: str | None = None) -> float:
    """The sample ``name`` (of ``robot``, when its samples carry a robot label)."""
    for (metric, labels), value in samples.items():
        if metric == name and (robot is None or labels_of(labels).get("robot") == robot):
            return value
    return 0.0


def histogram_quantile(
    before: dict[tuple[str, str], float],
    after: dict[tuple[str, str], float],
    name: str,
    q: float,
    robot: str | None = None,
) -> tuple[float, int]:
    """The ``q`` quantile (seconds, linear within its bucket) of the observations between two
    scrapes of histogram ``name`` (of ``robot`` only, when given), and how many there were."""
    buckets = []
    for (metric, labels), value in after.items():
        if metric == name + "_bucket":
            fields = labels_of(labels)
            if robot is not None and fields.get("robot") != robot:
                continue
            bound_text = fields["le"]
            bound = float("inf") if bound_text == "+Inf" else float(bound_text)
            buckets.append((bound, value - before.get((metric, labels), 0.0)))
    buckets.sort()
    if not buckets:
        return float("nan"), 0
    total = buckets[-1][1]
    if total <= 0:
        return float("nan"), 0
    rank = q * total
    previous_bound, previous_count = 0.0, 0.0
    for bound, count in buckets:
        if count >= rank:
            if bound == float("inf"):
                return previous_bound, int(total)
            share = (rank - previous_count) / max(count - previous_count, 1e-9)
            return previous_bound + share * (bound - previous_bound), int(total)
        previous_bound, previous_count = bound, count
    return previous_bound, int(total)
