"""``cobot-hmi demo`` as a newcomer runs it: a cell of emulated robots as processes of their own,
state in a fresh temporary directory, every address checked before a password is shown, and
emulators that end with the demo even when it is killed with SIGKILL."""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import signal
import socket
import ssl
import tempfile
from asyncio.subprocess import Process
from pathlib import Path

import httpx
import pytest

from conftest import _next_host, free_tcp_port
from process_support import (
    PIPE,
    PROCESS_DEADLINE_S,
    alive,
    all_ended,
    children,
    cli_process,
    read_until,
    wait_ready,
)
from service_support import DEADLINE_S, eventually_async


def demo_process(*args: str) -> contextlib.AbstractAsyncContextManager[Process]:
    """``cobot-hmi demo ARGS``, its stderr apart; killed (and reaped) at the end."""
    return cli_process("demo", *args, stderr=PIPE)


def _addresses(robots: int) -> tuple[list[str], list[str]]:
    """Fresh loopback addresses for the robots and the HMI, and the demo's flags for them."""
    hosts = [_next_host() for _ in range(robots)]
    hmi_host = _next_host()
    flags = [
        *(flag for host in hosts for flag in ("--robot-host", host)),
        "--robot-tcp-port",
        str(free_tcp_port(hosts[0])),
        "--control-port",
        "0",
        "--local-host",
        hmi_host,
        "--host",
        hmi_host,
        "--port",
        str(free_tcp_port(hmi_host)),
        "--rpi-ms",
        "20",
    ]
    return hosts, flags


async def _read_until_password(process: Process) -> list[str]:
    """The demo's stdout lines up to the one with the password, and the state line after it."""
    return await read_until(process, "with password") + await read_until(process, "state in")


async def test_two_robots_fresh_state_and_emulators_end_after_kill_9() -> None:
    hosts, flags = _addresses(2)
    async with demo_process(*flags) as demo:
        lines = await _read_until_password(demo)
        text = "".join(lines)
        assert "m1013 (M1013)" in text and "m0609 (M0609)" in text
        state_line = next(line for line in lines if "state in" in line)
        state_dir = Path(state_line.split("state in ")[1].split(" (")[0].strip())
        # A fresh temporary directory, not the user's state directory shared by every demo.
        assert state_dir.is_relative_to(tempfile.gettempdir())
        assert "removed at the end" in state_line
        assert (state_dir / "users.json").exists()  # written before the password is shown
        emulators = children(demo.pid)
        assert len(emulators) == 2, emulators
        assert all(alive(pid) for pid in emulators)
        base_url = next(line for line in lines if "HMI at" in line).split("HMI at ")[1].strip()
        async with httpx.AsyncClient(base_url=base_url, timeout=DEADLINE_S) as client:

            async def all_connected() -> bool:
                with contextlib.suppress(httpx.HTTPError):
                    answer = await client.get("/api/v1/robots")
                    return answer.status_code == 200 and all(
                        r["connection"] == "connected" and r["model"]
                        for r in answer.json()["robots"]
                    )
                return False

            await eventually_async(all_connected, PROCESS_DEADLINE_S)
            robots = (await client.get("/api/v1/robots")).json()["robots"]
        assert [(r["name"], r["host"]) for r in robots] == [
            ("m1013", hosts[0]),
            ("m0609", hosts[1]),
        ]
        assert all(r["connection"] == "connected" for r in robots), robots
        # Each arm says which it is (its identity, read by ListIdentity).
        assert [r["model"] for r in robots] == [
            "Doosan M1013 (emulated)",
            "Doosan M0609 (emulated)",
        ]
        demo.send_signal(signal.SIGKILL)
        await demo.wait()
        # The emulators end by themselves (PR_SET_PDEATHSIG), their addresses free again.
        await all_ended(emulators)
    for host in hosts:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.bind((host, 2222))


async def test_one_robot_and_the_state_dir_goes_at_the_end() -> None:
    _, flags = _addresses(1)
    async with demo_process("--robots", "1", *flags) as demo:
        lines = await _read_until_password(demo)
        state_line = next(line for line in lines if "state in" in line)
        state_dir = Path(state_line.split("state in ")[1].split(" (")[0].strip())
        assert "m0609" not in "".join(lines)
        assert len(children(demo.pid)) == 1
        assert (state_dir / "users.json").exists()
        demo.send_signal(signal.SIGINT)
        out, _ = await asyncio.wait_for(demo.communicate(), PROCESS_DEADLINE_S)
    assert demo.returncode == 0, out.decode()
    assert "cobot-hmi demo: stopped." in out.decode()
    assert not await asyncio.to_thread(state_dir.exists)


async def test_an_interrupt_before_the_service_runs_stops_a_demo_begun_with_it_ignored() -> None:
    """A demo started with SIGINT ignored (a script's background job; a test runner's worker
    passes that on) still stops on ``kill -INT``, even one sent right after the password,
    before its service has installed its own handler: the signal is never lost."""
    _, flags = _addresses(1)
    async with cli_process("demo", "--robots", "1", *flags, sigint_ignored=True) as demo:
        await read_until(demo, "with password")
        demo.send_signal(signal.SIGINT)
        await asyncio.wait_for(demo.wait(), PROCESS_DEADLINE_S)
    assert demo.returncode in (0, 130)


async def test_tls_with_the_plain_http_redirect() -> None:
    """``demo --tls --http-redirect-port``: HTTPS with the self-signed certificate whose
    fingerprint it prints, and plain HTTP beside it that only redirects to it."""
    _, flags = _addresses(1)
    host = flags[flags.index("--host") + 1]
    redirect_port = free_tcp_port(host)
    extra = ("--tls", "--http-redirect-port", str(redirect_port))
    async with demo_process("--robots", "1", *flags, *extra) as demo:
        text = "".join(await read_until(demo, "Ctrl-C stops all"))
        base_url = text.split("HMI at ")[1].split()[0].rstrip("/")
        assert base_url.startswith(f"https://{host}:")
        cert = Path(text.split("TLS certificate ")[1].split(" (self-signed)")[0])
        printed = text.split("SHA-256 fingerprint")[1].split()[0]
        assert f"plain HTTP on http://{host}:{redirect_port}/ redirects to it" in text
        trusted = ssl.create_default_context(cafile=str(cert))  # verified, host name included
        await wait_ready(base_url, demo, verify=trusted)
        async with httpx.AsyncClient(timeout=DEADLINE_S) as client:
            moved = await client.get(f"http://{host}:{redirect_port}/kiosk?x=1")
        assert moved.status_code == 301
        assert moved.headers["location"] == f"{base_url}/kiosk?x=1"
        https_port = int(base_url.rsplit(":", 1)[1])
        served = ssl.PEM_cert_to_DER_cert(
            await asyncio.to_thread(ssl.get_server_certificate, (host, https_port))
        )
        assert printed == ":".join(f"{byte:02X}" for byte in hashlib.sha256(served).digest())
        demo.send_signal(signal.SIGINT)
        await asyncio.wait_for(demo.wait(), PROCESS_DEADLINE_S)
    assert demo.returncode == 0


async def test_a_redirect_without_tls_is_refused_before_anything_starts() -> None:
    _, flags = _addresses(1)
    async with demo_process("--robots", "1", *flags, "--http-redirect-port", "8080") as demo:
        out, err = await asyncio.wait_for(demo.communicate(), PROCESS_DEADLINE_S)
    assert demo.returncode == 2
    assert "--http-redirect-port redirects to HTTPS: give --tls too" in err.decode()
    assert "password" not in out.decode()


@pytest.mark.parametrize("taken", ["emulator", "http"])
async def test_a_taken_address_ends_the_demo_before_any_password(taken: str) -> None:
    hosts, flags = _addresses(2)
    if taken == "emulator":
        # Another emulator (or anything) already serves the second robot's address.
        address = (hosts[1], int(flags[flags.index("--robot-tcp-port") + 1]))
    else:
        address = (flags[flags.index("--host") + 1], int(flags[flags.index("--port") + 1]))
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as holder:
        holder.bind(address)
        holder.listen()
        async with demo_process(*flags) as demo:
            out, err = await asyncio.wait_for(demo.communicate(), PROCESS_DEADLINE_S)
    assert demo.returncode == 2
    message = err.decode()
    assert f"{address[0]}:{address[1]} is taken" in message, message
    assert "password" not in out.decode()
    assert "EtherNet/IP target on" not in out.decode()  # nothing was started
