"""``cobot-hmi serve --tls-cert --tls-key --http-redirect-port`` as an operator runs it: the
flags, HTTPS on the port, plain HTTP beside it that only redirects; a key that does not fit
the certificate stops it at start with a message, before anything is served."""

from __future__ import annotations

import contextlib
from pathlib import Path

import httpx
import pytest

from cobot_hmi.emulator.target import Target
from conftest import free_tcp_port
from process_support import PIPE, PROCESS_DEADLINE_S, cli_process
from service_support import DEADLINE_S
from tls_support import TestCa
from waiting import eventually_async

pytestmark = pytest.mark.timeout(180)


async def test_serve_with_tls_and_the_redirect(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    ca = TestCa.create(tmp_path / "ca")
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    ca.issue(cert, key, plc_host)
    port, redirect_port = free_tcp_port(plc_host), free_tcp_port(plc_host)
    flags = [
        "serve",
        "--robot", robot_host,
        "--robot-tcp-port", str(target.tcp_port),
        "--local-host", plc_host,
        "--timeout-multiplier", "5",
        "--host", plc_host,
        "--port", str(port),
        "--state-dir", str(tmp_path / "state"),
        "--tls-cert", str(cert),
        "--tls-key", str(key),
        "--http-redirect-port", str(redirect_port),
    ]  # fmt: skip
    base_url = f"https://{plc_host}:{port}"
    async with (
        cli_process(*flags, stdout=PIPE, interrupt_first=True) as serve,
        httpx.AsyncClient(verify=ca.client_context(), timeout=DEADLINE_S) as client,
    ):

        async def ready() -> bool:
            assert serve.returncode is None, "the service exited"
            with contextlib.suppress(httpx.HTTPError):
                return (await client.get(f"{base_url}/readyz")).status_code == 200
            return False

        await eventually_async(ready, PROCESS_DEADLINE_S)
        answer = await client.get(f"{base_url}/api/v1/robots")
        assert answer.status_code == 200
        assert answer.headers["strict-transport-security"] == "max-age=31536000"
        moved = await client.get(f"http://{plc_host}:{redirect_port}/kiosk?x=1")
        assert moved.status_code == 301
        assert moved.headers["location"] == f"{base_url}/kiosk?x=1"


async def test_a_key_that_does_not_fit_stops_serve_at_start(tmp_path: Path) -> None:
    ca = TestCa.create(tmp_path / "ca")
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    ca.issue(cert, key, "127.0.0.1")
    ca.issue(tmp_path / "other.pem", tmp_path / "other-key.pem", "127.0.0.1")
    flags = [
        "serve",
        "--robot", "127.0.0.2",
        "--port", str(free_tcp_port("127.0.0.1")),
        "--state-dir", str(tmp_path / "state"),
        "--tls-cert", str(cert),
        "--tls-key", str(tmp_path / "other-key.pem"),
    ]  # fmt: skip
    async with cli_process(*flags, stdout=PIPE, stderr=PIPE) as serve:
        out, err = await serve.communicate()
    assert serve.returncode == 2, (out + err).decode()
    said = err.decode()
    assert "TLS:" in said and "not a PEM certificate and its matching private key" in said
