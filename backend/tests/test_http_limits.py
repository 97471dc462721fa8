"""The service's TCP bounds against the real ``cobot-hmi serve`` process: 1,100 idle
connections do not starve it, a connection that never sends a request is closed, and the
closings are counted in ``/metrics``. And with 1,100 idle connections held (descriptors past
1023), the robot's TCP session and class 1 connection dropped: the link reconnects (a
``select()`` loop could not watch the new sockets, and the cyclic thread died for good).

The service runs with the open-files limit of a typical Linux service (1024, soft and hard):
without the bounds it accepts connections until it runs out of descriptors, and every later
client waits in the kernel's queue for good. The test process itself needs more descriptors
than that and raises its own limit.
"""

from __future__ import annotations

import asyncio
import contextlib
import resource
from collections.abc import AsyncIterator
from pathlib import Path

import httpx
import pytest

from cobot_hmi.emulator.target import Target
from conftest import free_tcp_port
from process_support import PROCESS_DEADLINE_S, cli_process, wait_ready
from service_support import DEADLINE_S, emulator, eventually, eventually_async

pytestmark = pytest.mark.timeout(240)

SERVICE_FILES_LIMIT = 1024
IDLE_CONNECTIONS = 1100


@pytest.fixture
async def target(robot_host: str) -> AsyncIterator[Target]:
    async with emulator(robot_host) as target:
        yield target


@contextlib.asynccontextmanager
async def serve(
    target: Target,
    robot_host: str,
    plc_host: str,
    tmp_path: Path,
    *flags: str,
    files_limit: int = SERVICE_FILES_LIMIT,
) -> AsyncIterator[str]:
    """``cobot-hmi serve`` as a child process with ``files_limit`` files; its base URL once it
    is ready (connected to ``target``)."""
    port = free_tcp_port(plc_host)
    args = ["serve", "--robot", robot_host, "--robot-tcp-port", str(target.tcp_port)]
    args += ["--local-host", plc_host, "--timeout-multiplier", "5", "--host", plc_host]
    args += ["--port", str(port), "--state-dir", str(tmp_path), *flags]
    base_url = f"http://{plc_host}:{port}"
    with (tmp_path / "service.log").open("wb") as log:
        async with cli_process(*args, stdout=log, stderr=log, files_limit=files_limit) as process:
            try:
                await wait_ready(base_url, process)
            except BaseException:
                print((tmp_path / "service.log").read_text())
                raise
            yield base_url


def _raise_own_files_limit(needed: int) -> None:
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != resource.RLIM_INFINITY and soft < needed:
        if hard != resource.RLIM_INFINITY and hard < needed:
            pytest.skip(f"this test needs {needed} open files; the hard limit is {hard}")
        resource.setrlimit(resource.RLIMIT_NOFILE, (needed, hard))


async def _open_idle(host: str, port: int, count: int) -> list[asyncio.StreamWriter]:
    """``count`` TCP connections that never send anything (opened a batch at a time)."""
    writers: list[asyncio.StreamWriter] = []
    for start in range(0, count, 100):
        batch = await asyncio.gather(
            *(asyncio.open_connection(host, port) for _ in range(min(100, count - start)))
        )
        writers.extend(writer for _, writer in batch)
    return writers


async def test_idle_connections_do_not_starve_the_service(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    _raise_own_files_limit(IDLE_CONNECTIONS + 512)
    async with serve(target, robot_host, plc_host, tmp_path) as base_url:
        port = int(base_url.rsplit(":", 1)[1])
        idle = await _open_idle(plc_host, port, IDLE_CONNECTIONS)
        try:
            # A normal request, while all of them are held open: it must be answered (the
            # generous deadline is for a busy machine; without the bounds it never is).
            async with httpx.AsyncClient(base_url=base_url, timeout=60.0) as client:
                answer = await client.get("/api/v1/layout")
                assert answer.status_code == 200
                metrics = (await client.get("/metrics")).text
        finally:
            for writer in idle:
                writer.close()
    evicted = [line for line in metrics.splitlines() if 'reason="evicted"' in line]
    assert evicted and float(evicted[0].split()[-1]) > 0, metrics[-2000:]


async def test_a_connection_that_sends_no_request_is_closed(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    async with serve(
        target, robot_host, plc_host, tmp_path, "--http-idle-timeout-s", "1"
    ) as base_url:
        port = int(base_url.rsplit(":", 1)[1])
        reader, writer = await asyncio.open_connection(plc_host, port)
        try:
            writer.write(b"GET /healthz HTTP/1.1\r\n")  # a request head that never ends
            await writer.drain()
            # The service closes it (EOF) once the idle timeout has passed.
            assert await asyncio.wait_for(reader.read(), DEADLINE_S * 3) == b""
        finally:
            writer.close()
        async with httpx.AsyncClient(base_url=base_url, timeout=DEADLINE_S) as client:
            metrics = (await client.get("/metrics")).text
        assert 'cobot_hmi_http_connections_closed_total{reason="idle_closed"} 1.0' in metrics


async def test_the_link_reconnects_while_idle_connections_hold_descriptors_past_1023(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    _raise_own_files_limit(IDLE_CONNECTIONS + 512)
    robot_tcp_port = free_tcp_port(robot_host)
    async with (
        emulator(robot_host, tcp_port=robot_tcp_port) as first,
        serve(
            first,
            robot_host,
            plc_host,
            tmp_path,
            "--http-max-connections",
            str(IDLE_CONNECTIONS + 200),
            files_limit=4096,
        ) as base_url,
    ):
        port = int(base_url.rsplit(":", 1)[1])
        async with httpx.AsyncClient(base_url=base_url, timeout=60.0) as client:

            async def ready() -> int:
                return (await client.get("/readyz")).status_code

            ready_now: list[int] = []

            async def poll_ready(expected: int) -> None:
                async def now_expected() -> bool:
                    ready_now.append(await ready())
                    return ready_now[-1] == expected

                try:
                    await eventually_async(now_expected, PROCESS_DEADLINE_S)
                except AssertionError:
                    raise AssertionError(f"readyz never {expected}: {ready_now[-5:]}") from None

            await poll_ready(200)
            idle = await _open_idle(plc_host, port, IDLE_CONNECTIONS)
            try:
                # The robot goes away with its TCP session and class 1 connection...
                await first.stop()
                await poll_ready(503)
                # ...and comes back: the link must open new sockets (descriptors past
                # 1100 in the service) and reconnect.
                async with emulator(robot_host, tcp_port=robot_tcp_port) as second:
                    await poll_ready(200)
                    await eventually(lambda: bool(second.connections()), DEADLINE_S * 3)
                    health = await client.get("/healthz")
                    assert health.status_code == 200, health.text
                    metrics = (await client.get("/metrics")).text
                    # Reconnected by the same cyclic thread: it never died on the way.
                    assert "cobot_hmi_cyclic_thread_restarts_total 0" in metrics, [
                        line for line in metrics.splitlines() if "restarts" in line
                    ]
            finally:
                for writer in idle:
                    writer.close()
