"""A restart right after a stop starts at once. ``cobot-hmi demo`` is stopped by Ctrl-C
(SIGINT), by SIGTERM and by ``kill -9``, each time with its class 1 connection running, after
HTTP requests the server closed and with connections held open to its HTTP port and to the
emulator's EtherNet/IP and control ports; it is started again at once on the same
``--state-dir`` and addresses while the server ends of those connections still linger in
FIN-WAIT-2 or TIME-WAIT, and after ``kill -9`` beside what the crash left in the state
directory (the database's write-ahead log, the recording's open journal). So is a lone
``cobot-hmi emulator`` after ``kill -9``. The ports are the demo's own (TCP 44818 and 8081,
UDP 2222, HTTP 8000), on loopback addresses of this test's own."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import signal
import socket
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

from cobot_hmi.enip import encapsulation
from cobot_hmi.enip.encapsulation import Command
from cobot_hmi.history import segments
from conftest import _next_host
from process_support import PROCESS_DEADLINE_S, alive, all_ended, children, cli_process, read_until
from service_support import eventually, eventually_async

pytestmark = pytest.mark.timeout(300)

ENIP_PORT = 44818
CONTROL_PORT = 8081
HTTP_PORT = 8000

LINGERING = {"04": "FIN-WAIT-1", "05": "FIN-WAIT-2", "06": "TIME-WAIT", "0B": "CLOSING"}
"""The states of /proc/net/tcp (Linux include/net/tcp_states.h) the end that closed first
stays in after its process is gone: what a probe bound without SO_REUSEADDR counted as taken."""


def _proc_address(address: tuple[str, int]) -> str:
    """``host:port`` as /proc/net/tcp writes it (the address in the host's byte order)."""
    host, port = address
    return f"{socket.inet_aton(host)[::-1].hex().upper()}:{port:04X}"


def tcp_state(local: tuple[str, int], remote: tuple[str, int]) -> str | None:
    """The state of the TCP socket ``local`` ↔ ``remote`` (None: there is none)."""
    wanted = (_proc_address(local), _proc_address(remote))
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        fields = line.split()
        if (fields[1], fields[2]) == wanted:
            return fields[3]
    return None


@dataclass
class Held:
    """Connections this side keeps open while their server goes away: the server's end, the
    first to close, then waits in FIN-WAIT-2 for our FIN (and in TIME-WAIT after it)."""

    ends: list[tuple[tuple[str, int], tuple[str, int]]]

    def all_lingering(self) -> bool:
        """Every server end is in one of the ``LINGERING`` states."""
        return all(tcp_state(server, ours) in LINGERING for server, ours in self.ends)


async def _exchange(
    server: tuple[str, int], reader: asyncio.StreamReader, writer: asyncio.StreamWriter
) -> None:
    """One request and its answer: the server has accepted the connection (one still in its
    accept queue would be reset by the kernel, never lingering)."""
    if server[1] == ENIP_PORT:
        writer.write(
            encapsulation.encode(Command.REGISTER_SESSION, encapsulation.encode_register_session())
        )
        await reader.readexactly(encapsulation.HEADER_SIZE + 4)
    else:  # HTTP/1.1 keep-alive: the connection stays open, idle, after the answer
        writer.write(f"GET /healthz HTTP/1.1\r\nHost: {server[0]}\r\n\r\n".encode())
        head = await reader.readuntil(b"\r\n\r\n")
        length = next(
            int(line.split(b":")[1])
            for line in head.split(b"\r\n")
            if line.lower().startswith(b"content-length:")
        )
        await reader.readexactly(length)


@contextlib.asynccontextmanager
async def held_open(*servers: tuple[str, int]) -> AsyncIterator[Held]:
    writers = []
    held = Held([])
    try:
        for server in servers:
            reader, writer = await asyncio.open_connection(*server)
            writers.append(writer)
            await asyncio.wait_for(_exchange(server, reader, writer), PROCESS_DEADLINE_S)
            held.ends.append((server, writer.get_extra_info("sockname")))
        yield held
    finally:
        for writer in writers:
            writer.close()
            with contextlib.suppress(OSError):
                await writer.wait_closed()


async def connected_after_requests(base_url: str) -> None:
    """Until the service serves and holds its class 1 connection; then a few requests on
    connections the server closes (``Connection: close``), each leaving a TIME-WAIT on its port."""
    async with httpx.AsyncClient(
        base_url=base_url, timeout=PROCESS_DEADLINE_S, headers={"Connection": "close"}
    ) as client:

        async def connected() -> bool:
            with contextlib.suppress(httpx.HTTPError):
                robots = (await client.get("/api/v1/robots")).json()["robots"]
                return all(robot["connection"] == "connected" for robot in robots)
            return False

        await eventually_async(connected, PROCESS_DEADLINE_S)
        for _ in range(3):
            assert (await client.get("/healthz")).status_code == 200


def _closed(history: Path, journals: list[tuple[int, Path]]) -> bool:
    """None of ``journals`` is open any more (the recorder closed each into its segment)."""
    return not set(journals) & set(segments.list_journals(history, "m1013"))


async def test_the_demo_restarts_at_once_after_sigint_sigterm_and_kill_9(tmp_path: Path) -> None:
    robot_host, hmi_host = _next_host(), _next_host()
    state_dir = tmp_path / "state"
    flags = ["--robots", "1", "--robot-host", robot_host, "--local-host", hmi_host]
    flags += ["--host", hmi_host, "--state-dir", str(state_dir), "--rpi-ms", "20"]
    base_url = f"http://{hmi_host}:{HTTP_PORT}"
    servers = [(robot_host, ENIP_PORT), (robot_host, CONTROL_PORT), (hmi_host, HTTP_PORT)]
    history = state_dir / "history"
    async with contextlib.AsyncExitStack() as leftovers:
        previous: Held | None = None
        crash_journals: list[tuple[int, Path]] = []
        for stop in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL, None):
            async with cli_process("demo", *flags, interrupt_first=True) as demo:
                said = "".join(await read_until(demo, "Ctrl-C stops all"))
                # Every address passed the demo's check, and every listener is bound, ...
                assert "is taken" not in said and "with password" in said, said
                if previous is not None:
                    # ... beside the ends the last run's connections left behind. (After
                    # kill -9 the emulator ends on its parent's death, perhaps only now.)
                    await eventually(previous.all_lingering, PROCESS_DEADLINE_S)
                await connected_after_requests(base_url)
                if crash_journals:  # the restart closes the crash's journal into a segment
                    await eventually(
                        functools.partial(_closed, history, crash_journals), PROCESS_DEADLINE_S
                    )
                if stop is None:
                    break
                emulators = children(demo.pid)
                assert len(emulators) == 1, emulators
                if stop == signal.SIGKILL:
                    await eventually(
                        lambda: bool(segments.list_journals(history, "m1013")), PROCESS_DEADLINE_S
                    )
                previous = await leftovers.enter_async_context(held_open(*servers))
                demo.send_signal(stop)
                rest, _ = await asyncio.wait_for(demo.communicate(), PROCESS_DEADLINE_S)
                said += rest.decode(errors="replace")
                if stop == signal.SIGINT:
                    assert demo.returncode == 0, said
                    assert "cobot-hmi demo: stopped." in said
                    assert not any(alive(pid) for pid in emulators)  # stopped by the demo
                if stop == signal.SIGKILL:
                    assert demo.returncode == -signal.SIGKILL
                    # What the crash left: the database's write-ahead log, the open journal.
                    assert (state_dir / "hmi.db-wal").exists(), sorted(state_dir.iterdir())
                    crash_journals = segments.list_journals(history, "m1013")
                    assert crash_journals
                else:
                    await all_ended(emulators)
            # The next round starts the demo again at once.


async def test_a_lone_emulator_restarts_at_once_after_kill_9() -> None:
    host = _next_host()
    flags = ["emulator", "--host", host, "--no-discovery"]
    servers = [(host, ENIP_PORT), (host, CONTROL_PORT)]
    async with contextlib.AsyncExitStack() as leftovers:
        async with cli_process(*flags) as first:
            await read_until(first, "EtherNet/IP target on")
            held = await leftovers.enter_async_context(held_open(*servers))
            first.kill()
            await first.communicate()
        await eventually(held.all_lingering, PROCESS_DEADLINE_S)
        async with cli_process(*flags) as again:
            said = "".join(await read_until(again, "EtherNet/IP target on"))
            assert f"TCP {ENIP_PORT} UDP 2222" in said and f":{CONTROL_PORT}" in said, said
            assert held.all_lingering()
