"""The plant's tests' pieces: the real ``cobot-hmi plant`` process (its printed login read back),
its REST API read as any client would (httpx, a bearer token from the login), and an edge node
we did not write (pysparkplug in a venv of its own: ``tests/peers/pysparkplug_node.py``)."""

from __future__ import annotations

import asyncio
import contextlib
import re
import sys
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import pytest

from conftest import free_tcp_port
from process_support import cli_process, read_until, wait_ready
from waiting import eventually_async

REPO = Path(__file__).resolve().parents[2]
PEER_PYTHON = REPO / ".venv" / "pysparkplug-peer" / "bin" / "python"
PEER_SCRIPT = Path(__file__).resolve().parent / "peers" / "pysparkplug_node.py"
needs_pysparkplug = pytest.mark.skipif(
    not PEER_PYTHON.exists(), reason="pysparkplug's venv (make pysparkplug-peer)"
)


@dataclass
class Plant:
    process: asyncio.subprocess.Process
    base_url: str
    token: str
    client: httpx.AsyncClient

    async def nodes(self, **params: str) -> list[dict[str, Any]]:
        answer = await self.client.get("/api/v1/plant/nodes", params=params)
        assert answer.status_code == 200, answer.text
        result: list[dict[str, Any]] = answer.json()
        return result

    async def node(self, group: str, node: str) -> dict[str, Any] | None:
        return next(
            (n for n in await self.nodes() if n["group"] == group and n["node"] == node), None
        )

    async def get(self, path: str, **params: Any) -> Any:
        answer = await self.client.get(path, params=params)
        assert answer.status_code == 200, answer.text
        return answer.json()

    async def until(self, group: str, node: str, check: Any, timeout_s: float = 30.0) -> Any:
        """Until ``check(node)`` holds for the node as the API answers it; that node."""
        seen: dict[str, Any] = {}

        async def holds() -> bool:
            found = await self.node(group, node)
            seen["node"] = found
            return found is not None and bool(check(found))

        try:
            await eventually_async(holds, timeout_s)
        except AssertionError:
            raise AssertionError(f"not reached; the plant answers {seen.get('node')}") from None
        return seen["node"]


@contextlib.asynccontextmanager
async def plant_process(
    host: str, state_dir: Path, urls: list[str], *extra: str
) -> AsyncIterator[Plant]:
    """``cobot-hmi plant`` on ``host`` (a free port), logged in as the operator it printed."""
    port = free_tcp_port(host)
    flags = [flag for url in urls for flag in ("--mqtt-url", url)]
    async with cli_process(
        "plant", *flags, "--host", host, "--port", str(port), "--state-dir", str(state_dir), *extra
    ) as process:
        lines = await read_until(process, "log in as")
        found = re.search(r"log in as '([^']+)' with password '([^']+)'", lines[-1])
        assert found, lines
        base_url = f"http://{host}:{port}"
        await wait_ready(base_url, process, "/openapi.json")
        async with httpx.AsyncClient(base_url=base_url, timeout=30.0) as client:
            login = await client.post(
                "/api/v1/auth/login", json={"username": found[1], "password": found[2]}
            )
            assert login.status_code == 200, login.text
            token = login.json()["token"]
            client.headers["Authorization"] = f"Bearer {token}"
            drain = asyncio.create_task(_drain(process))
            try:
                yield Plant(process, base_url, token, client)
            finally:
                drain.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await drain


async def _drain(process: asyncio.subprocess.Process) -> None:
    """Its log read on, so a full pipe never blocks it."""
    assert process.stdout is not None
    while await process.stdout.readline():
        pass


@dataclass
class PeerNode:
    """pysparkplug's edge node, one device, driven by lines (see the peer's docstring)."""

    process: asyncio.subprocess.Process
    lines: list[str] = field(default_factory=list)

    async def send(self, command: str) -> None:
        assert self.process.stdin is not None
        self.process.stdin.write(command.encode() + b"\n")
        await self.process.stdin.drain()
        word = command.split(maxsplit=1)[0]
        if word != "death":
            await self.wait_for(f"done {word}", count=self.count(f"done {word}") + 1)

    def count(self, prefix: str) -> int:
        return sum(line.startswith(prefix) for line in self.lines)

    async def wait_for(self, prefix: str, count: int = 1, timeout_s: float = 30.0) -> None:
        assert self.process.stdout is not None
        async with asyncio.timeout(timeout_s):
            while self.count(prefix) < count:
                line = (await self.process.stdout.readline()).decode(errors="replace")
                assert line, f"the peer ended before {prefix!r}: {self.lines}"
                self.lines.append(line.strip())


@contextlib.asynccontextmanager
async def pysparkplug_node(
    host: str, port: int, group: str, node: str, device: str
) -> AsyncIterator[PeerNode]:
    process = await asyncio.create_subprocess_exec(
        str(PEER_PYTHON),
        str(PEER_SCRIPT),
        host,
        str(port),
        group,
        node,
        device,
        stdin=asyncio.subprocess.PIPE,
        stdout=asyncio.subprocess.PIPE,
        stderr=sys.stderr,
    )
    peer = PeerNode(process)
    try:
        await peer.wait_for("ready")
        yield peer
    finally:
        if process.returncode is None:
            process.kill()
        await process.communicate()
