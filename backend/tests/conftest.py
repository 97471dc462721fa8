"""Shared fixtures: every test gets loopback addresses of its own, and leaks fail the test.

All of 127.0.0.0/8 routes to ``lo`` on Linux, so giving each test its own pair of addresses lets
the emulator and the scanner each own UDP 2222 (as a robot and a PLC would on a real network)
while several test runs share the machine. Nothing here ever leaves the loopback range.
"""

from __future__ import annotations

import gc
import itertools
import logging
import os
import socket
from collections.abc import AsyncIterator, Iterator

import pytest
from hypothesis import HealthCheck
from hypothesis import settings as hypothesis_settings

from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings

# Hypothesis's timing checks measure the machine, not the code under test: on a loaded 2-core
# machine (a fresh clone's suite beside a bench) drawing a frame or running an example takes
# longer, and "input generation is slow" failed test_codec once at load 12. Every property and
# example count stays; only the clock is not judged.
hypothesis_settings.register_profile(
    "cobot-hmi", suppress_health_check=[HealthCheck.too_slow], deadline=None
)
hypothesis_settings.load_profile("cobot-hmi")

# 127.<a>.<b>.<c>: <a> from the pytest run's process id keeps concurrent runs apart; under
# pytest-xdist each worker (its parent is the run's process) has a range of <b> of its own.
_XDIST_WORKER = os.environ.get("PYTEST_XDIST_WORKER")  # "gw0", "gw1", ... under xdist
_RUN_PID = os.getppid() if _XDIST_WORKER else os.getpid()
_PROCESS_OCTET = 10 + _RUN_PID % 200
_WORKER_INDEX = int(_XDIST_WORKER.removeprefix("gw")) if _XDIST_WORKER else 0
_THIRD_OCTETS = 250 // max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
_HOSTS = itertools.count(1)


def _next_host() -> str:
    n = next(_HOSTS)
    third = _WORKER_INDEX * _THIRD_OCTETS + (n // 250) % _THIRD_OCTETS
    return f"127.{_PROCESS_OCTET}.{third}.{n % 250 + 2}"


@pytest.fixture
def robot_host() -> str:
    """A fresh loopback address for the emulated robot (the target)."""
    return _next_host()


@pytest.fixture
def plc_host() -> str:
    """A fresh loopback address for the scanner (the originator)."""
    return _next_host()


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """A TCP port free on ``host`` right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        port: int = s.getsockname()[1]
        return port


PUMP_IMPLEMENTATIONS = ("native", "python")
"""The cyclic pump's two implementations (``cobot_hmi.native``, chosen by ``COBOT_HMI_PUMP``)."""


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "both_pumps: run each test once with the native and once with the pure-Python pump",
    )


SLOW_MODULES_FIRST: tuple[str, ...] = (
    "test_history_service.py",
    "test_node_selection.py",
    "test_cycles_service.py",
    "test_demo.py",
    "test_session_idle.py",
    "test_plant_nats_cluster.py",
    "test_health_service.py",
    "test_health_period_baseline.py",
    "test_history_replay.py",
    "test_history_storage.py",
    "test_slow_target.py",
    "test_opcua.py",
    "test_opcua_security_peers.py",
    "test_sparkplug_replay_peers.py",
    "test_restart.py",
    "test_history_crash.py",
    "test_sparkplug_doors.py",
    "test_sparkplug_faults.py",
    "test_codec.py",
    "test_http_limits.py",
    "test_service_process.py",
    "test_service_robots.py",
    "test_rest_bounds_schemathesis.py",
    "test_emulator_hardening.py",
    "test_history_disk_full.py",
    "test_hardening.py",
    "test_emulator_scenarios.py",
    "test_alarm_words_and_consequences.py",
    "test_service_api.py",
    "test_class1_cycle.py",
    "test_service_stream.py",
)
"""The modules whose tests take longest in all (``--durations`` summed by module, 4 workers on
2 cores, measured 2026-12-07), slowest first.
pytest-xdist (``--dist loadfile``) hands a worker the next file as it frees up, in collection
order: started first, these no longer leave one worker alone on a minute-long file at the end
while the other idles."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    rank = {name: i for i, name in enumerate(SLOW_MODULES_FIRST)}
    # A stable sort: the tests of a module, and the other modules, keep their order.
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    if metafunc.definition.get_closest_marker("both_pumps") is not None:
        metafunc.parametrize("pump_implementation", PUMP_IMPLEMENTATIONS, indirect=True)


@pytest.fixture(autouse=True)
def pump_implementation(
    request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> str | None:
    """In a module marked ``both_pumps``, the cyclic pump every endpoint of the test uses
    (``native`` fails the test if the extension is missing); elsewhere None (the default)."""
    implementation: str | None = getattr(request, "param", None)
    if implementation is not None:
        monkeypatch.setenv("COBOT_HMI_PUMP", implementation)
    return implementation


class _PendingTaskLog(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        if "destroyed but it is pending" in message or "exception was never retrieved" in message:
            self.messages.append(message)


@pytest.fixture(autouse=True, scope="module")
def _earlier_objects_frozen() -> Iterator[None]:
    """What the worker held before this module (the libraries' modules, the session's fixtures:
    about 250,000 objects) is kept out of the cyclic garbage collector's way while the module's
    tests run (``gc.freeze``): each test's own collection (``_no_leaked_tasks``) traverses what
    the module made, not the whole worker again. A full collection after every test took 0.24 s
    on average: 245 of the 530 CPU-s of a whole pytest run (307 s wall on 2 cores; 233 s with
    the freeze). At the module's end everything is traversed once more, so its fixtures' garbage
    is collected and checked as well."""
    gc.collect()
    gc.freeze()
    yield
    gc.unfreeze()
    gc.collect()


@pytest.fixture(autouse=True)
def _no_leaked_tasks() -> Iterator[None]:
    """Fail a test that leaves an asyncio task pending or an exception unretrieved.

    Unclosed sockets and running subprocesses are caught by ``filterwarnings`` in
    pyproject.toml, which turns their ``ResourceWarning`` into an error.
    """
    handler = _PendingTaskLog()
    logger = logging.getLogger("asyncio")
    logger.addHandler(handler)
    try:
        yield
        gc.collect()
    finally:
        logger.removeHandler(handler)
    assert not handler.messages, f"test leaked asyncio tasks: {handler.messages}"


@pytest.fixture
def robot() -> StaticRobot:
    """A robot standing still whose outputs clear when the owner goes idle (the default of the
    class 1 tests; a module that needs another robot defines its own ``robot``)."""
    return StaticRobot(IdleBehaviour.CLEAR)


@pytest.fixture
async def target(robot_host: str, robot: StaticRobot) -> AsyncIterator[Target]:
    """Our EtherNet/IP target on its own loopback address, TCP port picked by the kernel."""
    emulator = Target(TargetSettings(host=robot_host, tcp_port=0), robot)
    await emulator.start()
    try:
        yield emulator
    finally:
        await emulator.stop()
