"""The one way the tests run ``cobot-hmi`` as a process of its own (``serve``, ``demo``,
``emulator``, ``export``): started with unbuffered output, and at the end stopped (SIGINT first
when asked, else SIGKILL) and reaped whatever happened, so no test leaves a process or a pipe
behind. Beside it what the tests wait for on such a process: a line of its output, its HTTP
readiness, its children and their end."""

from __future__ import annotations

import asyncio
import contextlib
import os
import resource
import signal
import ssl
import sys
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import IO, Any

import httpx

from service_support import DEADLINE_S, eventually, eventually_async

PROCESS_DEADLINE_S = DEADLINE_S * 9
"""A process of its own imports the whole service before it says anything: on a busy machine
that alone takes seconds, so its deadlines are wider than those of the in-process tests."""

PIPE = asyncio.subprocess.PIPE
STDOUT = asyncio.subprocess.STDOUT
DEVNULL = asyncio.subprocess.DEVNULL


def _preexec(files_limit: int | None, sigint_ignored: bool) -> Callable[[], None] | None:
    """What the child does before it runs the command (``None``: nothing)."""
    if files_limit is None and not sigint_ignored:
        return None
    limit = _limit_files(files_limit) if files_limit is not None else None

    def before_exec() -> None:
        if limit is not None:
            limit()
        if sigint_ignored:
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # kept across exec

    return before_exec


def _limit_files(limit: int) -> Callable[[], None]:
    def in_child() -> None:  # between fork and exec
        resource.setrlimit(resource.RLIMIT_NOFILE, (limit, limit))

    return in_child


@contextlib.asynccontextmanager
async def cli_process(
    *args: str,
    stdout: int | IO[Any] = PIPE,
    stderr: int | IO[Any] = STDOUT,
    interrupt_first: bool = False,
    files_limit: int | None = None,
    sigint_ignored: bool = False,
) -> AsyncIterator[asyncio.subprocess.Process]:
    """``cobot-hmi ARGS`` as a child process (with ``files_limit`` open files, soft and hard,
    if given). At the end, if it still runs: SIGINT and up to ``PROCESS_DEADLINE_S`` for a
    clean stop when ``interrupt_first`` (a demo stops its emulators itself then), else SIGKILL;
    reaped (its pipes read to their end) in any case. ``sigint_ignored``: started with SIGINT
    ignored, as a script's background job or a test runner's worker passes it on."""
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        *args,
        stdout=stdout,
        stderr=stderr,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
        preexec_fn=_preexec(files_limit, sigint_ignored),
    )
    try:
        yield process
    finally:
        if process.returncode is None and interrupt_first:
            process.send_signal(signal.SIGINT)
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(process.wait(), PROCESS_DEADLINE_S)
        if process.returncode is None:
            process.kill()
        await process.communicate()


async def read_until(
    process: asyncio.subprocess.Process, marker: str, timeout_s: float = PROCESS_DEADLINE_S
) -> list[str]:
    """The lines ``process`` writes to its stdout up to the first that holds ``marker``."""
    assert process.stdout is not None
    lines: list[str] = []
    async with asyncio.timeout(timeout_s):
        while not lines or marker not in lines[-1]:
            line = (await process.stdout.readline()).decode(errors="replace")
            assert line, f"it ended before {marker!r}:\n" + "".join(lines)
            lines.append(line)
    return lines


async def wait_ready(
    base_url: str,
    process: asyncio.subprocess.Process,
    path: str = "/readyz",
    verify: ssl.SSLContext | bool = True,
) -> None:
    """Until the service at ``base_url`` answers ``path`` with 200 (it fails if ``process``
    ends first); ``verify``: how HTTPS is trusted (httpx's)."""
    async with httpx.AsyncClient(base_url=base_url, timeout=DEADLINE_S, verify=verify) as client:

        async def ready() -> bool:
            assert process.returncode is None, "the service exited"
            with contextlib.suppress(httpx.HTTPError):
                return (await client.get(path)).status_code == 200
            return False

        await eventually_async(ready, PROCESS_DEADLINE_S)


def children(pid: int) -> list[int]:
    """The processes ``pid`` started (Linux ``/proc``)."""
    found: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        found.extend(int(part) for part in (task / "children").read_text().split())
    return found


def alive(pid: int) -> bool:
    """Not ended (a zombie has ended: it only waits for its parent to reap it)."""
    try:
        status = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return status.rsplit(")", 1)[1].split()[0] != "Z"


async def all_ended(pids: list[int]) -> None:
    """Until none of ``pids`` runs any more."""
    await eventually(lambda: not any(alive(pid) for pid in pids), PROCESS_DEADLINE_S)
