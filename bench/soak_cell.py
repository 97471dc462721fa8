"""``bench/soak``'s cell: the processes it runs and restarts, and the tmpfs under the service.

The demo's two robots (``cobot-hmi demo``: an M1013 with seed 1 and an M0609 with seed 2), each
an emulator process with its control API, on fresh loopback addresses; the service holding a
class 1 connection to each at its own RPI, with the recorder, the alarms and Sparkplug B to a
local Mosquitto; the service's state directory on a tmpfs of its own (mounted here, unmounted
by ``close`` whatever happened). Logs and the configuration stay on the ordinary disk, so a full
state directory never hides what the processes said.
"""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from proc_stats import process_cpu_s, process_figures
from service_bench_support import (
    BENCH_USER,
    Mosquitto,
    _accepts,
    _cli,
    _wait,
    free_port,
    loopback_cell,
    stop_process,
)

from cobot_hmi.service.access.users import Role, UsersFile

DEMO_ROBOTS = (("m1013", "M1013", 1), ("m0609", "M0609", 2))
"""Name, model and seed of the demo's robots (``cli/demo_verb.py`` ``DEMO_ROBOTS``)."""
READY_POLL_S = 0.02
"""How often a restarted process is asked whether it accepts connections (the fault's end)."""


@dataclass
class Robot:
    name: str
    model: str
    seed: int
    rpi_ms: float
    host: str
    tcp_port: int
    control_port: int
    process: subprocess.Popen[bytes] | None = None
    starts: int = 0

    @property
    def control_url(self) -> str:
        return f"http://{self.host}:{self.control_port}"


@dataclass
class Sample:
    """One process's figures at one minute."""

    rss_bytes: int
    fds: int
    threads: int
    cpu_s: float


@dataclass
class Cell:
    robots: list[Robot]
    service_host: str
    http_port: int
    work: Path
    state: Path
    tmpfs_mib: int
    robot_niceness: int
    service_args: list[str] = field(default_factory=list)
    broker: Mosquitto | None = None
    service: subprocess.Popen[bytes] | None = None
    mounted: bool = False

    @classmethod
    def create(cls, rpi_ms: list[float], tmpfs_mib: int, robot_niceness: int) -> Cell:
        hosts, service_host = loopback_cell(len(DEMO_ROBOTS))
        robots = [
            Robot(name, model, seed, rpi, host, free_port(host), free_port(host))
            for (name, model, seed), rpi, host in zip(DEMO_ROBOTS, rpi_ms, hosts, strict=True)
        ]
        work = Path(tempfile.mkdtemp(prefix="cobot-soak-"))
        (work / "logs").mkdir()
        state = work / "state"
        state.mkdir()
        return cls(
            robots, service_host, free_port(service_host), work, state, tmpfs_mib, robot_niceness
        )

    @property
    def base_url(self) -> str:
        return f"http://{self.service_host}:{self.http_port}"

    def ws_url(self, robot: str) -> str:
        return f"ws://{self.service_host}:{self.http_port}/api/v1/robots/{robot}/stream"

    def robot(self, name: str) -> Robot:
        return next(r for r in self.robots if r.name == name)

    # ------------------------------------------------------------------ the tmpfs

    def mount(self) -> None:
        if os.geteuid() != 0:
            raise SystemExit("bench/soak mounts a tmpfs for the service's state: run it as root")
        subprocess.run(
            [
                "mount",
                "-t",
                "tmpfs",
                "-o",
                f"size={self.tmpfs_mib}m,mode=0700",
                "cobot-soak",
                str(self.state),
            ],
            check=True,
        )
        self.mounted = True

    def unmount(self) -> None:
        if not self.mounted:
            return
        if subprocess.run(["umount", str(self.state)], check=False).returncode != 0:
            # Something still holds a file there: detach it now, freed when they let go.
            subprocess.run(["umount", "-l", str(self.state)], check=False)
        self.mounted = False

    def state_usage(self) -> tuple[int, int]:
        """Bytes used and the tmpfs's size."""
        stat = os.statvfs(self.state)
        return (stat.f_blocks - stat.f_bfree) * stat.f_frsize, stat.f_blocks * stat.f_frsize

    # ------------------------------------------------------------------ processes

    def start_emulator(self, robot: Robot) -> None:
        """Start (or start again) a robot's emulator; return once it accepts TCP."""
        robot.starts += 1
        robot.process = _cli(
            "emulator",
            "--host",
            robot.host,
            "--tcp-port",
            str(robot.tcp_port),
            "--control-port",
            str(robot.control_port),
            "--model",
            robot.model,
            "--seed",
            str(robot.seed),
            log=self.work / "logs" / f"emulator-{robot.name}-{robot.starts}.log",
            niceness=self.robot_niceness,
        )
        _wait(
            functools.partial(_accepts, robot.host, robot.tcp_port),
            f"emulator {robot.name}",
            robot.process,
            30,
            READY_POLL_S,
        )

    def kill_emulator(self, robot: Robot) -> None:
        """``kill -9``: no Forward Close, no goodbye."""
        assert robot.process is not None
        robot.process.send_signal(signal.SIGKILL)
        robot.process.wait()

    def start(self, mqtt: bool = True) -> None:
        UsersFile(self.state / "users.json").add(BENCH_USER[0], Role.OPERATOR, BENCH_USER[1])
        config = self.work / "cell.toml"
        config.write_text(
            "".join(
                f'[[robots]]\nname = "{r.name}"\nhost = "{r.host}"\ntcp_port = {r.tcp_port}\n'
                f"rpi_ms = {r.rpi_ms:g}\n\n"
                for r in self.robots
            ),
            encoding="utf-8",
        )
        for robot in self.robots:
            self.start_emulator(robot)
        self.broker = Mosquitto(self.service_host, self.work)
        self.broker.start()
        self.service = _cli(
            "serve",
            "--config",
            str(config),
            "--local-host",
            self.service_host,
            "--host",
            self.service_host,
            "--port",
            str(self.http_port),
            "--state-dir",
            str(self.state),
            *(["--mqtt-url", self.broker.url, "--sparkplug-node", "soak"] if mqtt else []),
            *self.service_args,
            log=self.work / "logs" / "service.log",
        )
        _wait(self._ready, "service", self.service, 60)

    def _ready(self) -> bool:
        import urllib.request

        opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))
        with opener.open(self.base_url + "/readyz", timeout=5) as answer:
            return b'"ready":true' in answer.read()

    def processes(self) -> dict[str, int]:
        """The live processes by role: their pids."""
        out: dict[str, int] = {}
        if self.service is not None and self.service.poll() is None:
            out["service"] = self.service.pid
        for robot in self.robots:
            if robot.process is not None and robot.process.poll() is None:
                out[f"emulator {robot.name}"] = robot.process.pid
        broker = self.broker.process if self.broker is not None else None
        if broker is not None and broker.poll() is None:
            out["mosquitto"] = broker.pid
        out["bench"] = os.getpid()
        return out

    def close(self) -> None:
        """Stop everything (the service first: its Forward Closes reach live emulators), then
        unmount the tmpfs. Safe to call more than once and after any failure."""
        try:
            for process in [self.service, *(r.process for r in self.robots)]:
                stop_process(process, 20)
            if self.broker is not None:
                self.broker.stop()
        finally:
            self.unmount()


def sample(pid: int) -> Sample | None:
    try:
        rss, fds, threads = process_figures(pid)
        return Sample(rss, fds, threads, process_cpu_s(pid))
    except (FileNotFoundError, ProcessLookupError):
        return None
