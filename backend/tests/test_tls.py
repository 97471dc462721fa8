"""HTTPS and WSS without a proxy (``service/api/tls*.py``): the service on uvicorn with a
certificate its own test CA issued, real TLS handshakes from Python's ``ssl``, httpx and
websockets trusting that CA only; the redirecting plain-HTTP listener; a certificate replaced
on disk while the service runs."""

from __future__ import annotations

import asyncio
import hashlib
import socket
import ssl
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import orjson
import pytest
from prometheus_client.parser import text_string_to_metric_families
from websockets.asyncio.client import connect
from websockets.exceptions import InvalidStatus
from websockets.typing import Origin

from cobot_hmi.emulator.target import Target
from cobot_hmi.service.api.tls import TlsError, fingerprint_of, not_after_of, server_context
from cobot_hmi.service.api.tls_redirect import redirect_listener
from cobot_hmi.service.api.tls_selfsigned import self_signed_pair
from cobot_hmi.service.config.loading import load_settings
from cobot_hmi.service.service_settings import ServiceSettings, SettingsError
from conftest import free_tcp_port
from service_support import DEADLINE_S, OPERATOR, running_service, service_settings
from tls_support import TestCa

pytestmark = pytest.mark.timeout(120)


@dataclass
class Https:
    settings: ServiceSettings
    ca: TestCa
    cert: Path
    key: Path
    der: bytes
    """The served certificate at the start."""

    @property
    def base_url(self) -> str:
        return f"https://{self.settings.web.host}:{self.settings.web.port}"

    def client(self, token: str | None = None) -> httpx.AsyncClient:
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        return httpx.AsyncClient(
            base_url=self.base_url,
            verify=self.ca.client_context(),
            headers=headers,
            timeout=DEADLINE_S,
        )

    async def login(self) -> httpx.Response:
        async with self.client() as client:
            return await client.post(
                "/api/v1/auth/login", json={"username": OPERATOR[0], "password": OPERATOR[1]}
            )


@pytest.fixture
async def https(
    target: Target, robot_host: str, plc_host: str, tmp_path: Path
) -> AsyncIterator[Https]:
    ca = TestCa.create(tmp_path / "ca")
    cert, key = tmp_path / "tls" / "cert.pem", tmp_path / "tls" / "key.pem"
    cert.parent.mkdir()
    der = ca.issue(cert, key, plc_host)
    settings = service_settings(
        robot_host, target.tcp_port, plc_host, tmp_path, tls_cert=cert, tls_key=key
    )
    async with running_service(settings):
        yield Https(settings, ca, cert, key, der)


def handshake(host: str, port: int, context: ssl.SSLContext) -> tuple[str | None, bytes | None]:
    """A bare TLS handshake: the version agreed and the server's certificate (DER)."""
    with (
        socket.create_connection((host, port), timeout=DEADLINE_S) as raw,
        context.wrap_socket(raw, server_hostname=host) as tls,
    ):
        return tls.version(), tls.getpeercert(binary_form=True)


async def test_a_handshake_with_the_plants_ca(https: Https) -> None:
    host, port = https.settings.web.host, https.settings.web.port
    version, der = await asyncio.to_thread(handshake, host, port, https.ca.client_context())
    assert version in ("TLSv1.2", "TLSv1.3")
    assert der == https.der
    # Another CA's client refuses it: the check is real.
    stranger = TestCa.create(https.cert.parent.parent / "stranger")
    with pytest.raises(ssl.SSLCertVerificationError):
        await asyncio.to_thread(handshake, host, port, stranger.client_context())
    async with https.client() as client:
        answer = await client.get("/api/v1/robots")
    assert answer.status_code == 200, answer.text
    assert answer.headers["strict-transport-security"] == "max-age=31536000"


async def test_tls_1_1_is_refused(https: Https) -> None:
    host, port = https.settings.web.host, https.settings.web.port

    def old_client(maximum: ssl.TLSVersion) -> ssl.SSLContext:
        context = https.ca.client_context()
        context.set_ciphers("DEFAULT:@SECLEVEL=0")  # a client that would still speak TLS 1.1
        context.minimum_version = ssl.TLSVersion.TLSv1
        context.maximum_version = maximum
        return context

    with pytest.raises(ssl.SSLError) as refused:
        await asyncio.to_thread(handshake, host, port, old_client(ssl.TLSVersion.TLSv1_1))
    # The server answered the hello by closing (asyncio's TLS, or its protocol_version alert);
    # not the client's own refusal to offer TLS 1.1 (NO_PROTOCOLS_AVAILABLE).
    refusal = str(refused.value).upper()
    assert isinstance(refused.value, ssl.SSLEOFError) or "VERSION" in refusal, refusal
    assert "NO_PROTOCOLS" not in refusal
    version, _ = await asyncio.to_thread(handshake, host, port, old_client(ssl.TLSVersion.TLSv1_2))
    assert version == "TLSv1.2"  # the same client, allowed 1.2, gets in


async def test_the_session_cookie_is_secure(https: Https) -> None:
    answer = await https.login()
    assert answer.status_code == 200, answer.text
    cookie = answer.headers["set-cookie"]
    flags = {part.strip().split("=")[0].lower() for part in cookie.split(";")}
    assert {"secure", "httponly", "samesite"} <= flags, cookie
    assert "samesite=strict" in cookie.lower()


async def test_the_stream_over_wss_and_its_origin_check(https: Https) -> None:
    token = (await https.login()).json()["token"]
    url = f"wss://{https.settings.web.host}:{https.settings.web.port}/api/v1/stream"
    own = f"https://{https.settings.web.host}:{https.settings.web.port}"
    headers = {"Authorization": f"Bearer {token}"}
    async with connect(
        url, ssl=https.ca.client_context(), additional_headers=headers, origin=Origin(own)
    ) as stream:
        hello = orjson.loads(await asyncio.wait_for(stream.recv(), DEADLINE_S))
        assert hello["type"] == "hello"
        frames = orjson.loads(await asyncio.wait_for(stream.recv(), DEADLINE_S))
        assert frames["type"] in ("frames", "status", "event")
    # The page's origin is https://…: the same host and port over http:// is another origin.
    plain = f"http://{https.settings.web.host}:{https.settings.web.port}"
    with pytest.raises(InvalidStatus) as refused:
        async with connect(
            url, ssl=https.ca.client_context(), additional_headers=headers, origin=Origin(plain)
        ):
            pass
    assert refused.value.response.status_code == 403


async def test_a_replaced_certificate_is_served_without_a_restart(https: Https) -> None:
    host, port = https.settings.web.host, https.settings.web.port
    client = https.ca.client_context()
    _, first = await asyncio.to_thread(handshake, host, port, client)
    assert first == https.der
    # A broken pair (the key of another certificate): the last good one stays.
    spare = https.cert.parent / "spare"
    spare.mkdir()
    https.ca.issue(spare / "cert.pem", spare / "key.pem", host, name="other")
    https.key.write_bytes((spare / "key.pem").read_bytes())
    _, still = await asyncio.to_thread(handshake, host, port, client)
    assert still == https.der
    # The rotation done (certificate and key of one pair): the next handshake has it.
    renewed = https.ca.issue(https.cert, https.key, host, name="renewed")
    _, now = await asyncio.to_thread(handshake, host, port, client)
    assert now == renewed and now != https.der
    async with https.client() as session:  # and HTTP on it works
        assert (await session.get("/api/v1/robots")).status_code == 200
        # The operators see both in /metrics, and when the certificate served now expires.
        metrics = (await session.get("/metrics")).text
    samples = {
        sample.name: sample.value
        for family in text_string_to_metric_families(metrics)
        for sample in family.samples
    }
    assert samples["cobot_hmi_tls_certificate_reloads_total"] == 1
    assert samples["cobot_hmi_tls_certificate_reload_failures_total"] == 1
    expiry = samples["cobot_hmi_tls_certificate_expiry_timestamp_seconds"]
    assert expiry == pytest.approx(not_after_of(https.cert))  # the renewed certificate's


async def test_the_plain_http_listener_only_redirects(https: Https) -> None:
    host, https_port = https.settings.web.host, https.settings.web.port
    port = free_tcp_port(host)
    allowed = ("localhost", "ip")
    async with (
        redirect_listener(host, port, https_port, allowed),
        httpx.AsyncClient(base_url=f"http://{host}:{port}", timeout=DEADLINE_S) as plain,
    ):
        answer = await plain.get("/panel/robots?x=1")
        assert answer.status_code == 301
        assert answer.headers["location"] == f"https://{host}:{https_port}/panel/robots?x=1"
        posted = await plain.post("/api/v1/auth/login", json={"username": "a", "password": "b"})
        assert posted.status_code == 308
        assert posted.headers["location"] == f"https://{host}:{https_port}/api/v1/auth/login"
        assert "set-cookie" not in posted.headers
        wrong_host = await plain.get("/", headers={"Host": "evil.example"})
        assert wrong_host.status_code == 400
        # Followed, it lands on the HTTPS service.
        async with httpx.AsyncClient(
            verify=https.ca.client_context(), follow_redirects=True, timeout=DEADLINE_S
        ) as browser:
            landed = await browser.get(f"http://{host}:{port}/api/v1/robots")
        assert landed.status_code == 200 and str(landed.url).startswith("https://")
        # Not HTTP at all: an answer of 400, the connection closed.
        reader, writer = await asyncio.open_connection(host, port)
        writer.write(b"\x16\x03\x01 not http\r\n\r\n")
        said = await asyncio.wait_for(reader.read(), DEADLINE_S)
        writer.close()
        assert said.startswith(b"HTTP/1.1 400")


def test_settings_want_both_files_and_tls_for_the_redirect(tmp_path: Path) -> None:
    ca = TestCa.create(tmp_path)
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    ca.issue(cert, key, "127.0.0.1")
    robot = {"robot_host": "127.0.0.2", "state_dir": tmp_path}
    settings = load_settings({**robot, "tls_cert": cert, "tls_key": key, "http_redirect_port": 80})
    assert settings.tls.tls_enabled and settings.tls.http_redirect_port == 80
    with pytest.raises(SettingsError, match="tls_cert and tls_key go together"):
        load_settings({**robot, "tls_cert": cert})
    with pytest.raises(SettingsError, match="http_redirect_port redirects to HTTPS"):
        load_settings({**robot, "http_redirect_port": 8080})
    with pytest.raises(SettingsError, match=r"missing\.pem"):
        load_settings({**robot, "tls_cert": tmp_path / "missing.pem", "tls_key": key})
    with pytest.raises(TlsError, match="not a PEM certificate and its matching private key"):
        server_context(cert, ca.ca_file)


async def test_the_demos_self_signed_pair(tmp_path: Path) -> None:
    cert, key, made = self_signed_pair(tmp_path, ["127.0.0.9", "hmi.local"])
    assert made and cert.parent == tmp_path / "tls"
    assert key.stat().st_mode & 0o777 == 0o600
    fingerprint = fingerprint_of(cert)
    der = ssl.PEM_cert_to_DER_cert(cert.read_text())
    assert fingerprint.replace(":", "") == hashlib.sha256(der).hexdigest().upper()
    assert len(fingerprint) == 32 * 3 - 1
    again = self_signed_pair(tmp_path, ["127.0.0.9"])
    assert again == (cert, key, False) and fingerprint_of(cert) == fingerprint  # kept
    # A client that pins it (as a browser's exception does) completes a handshake, the name
    # checked against the certificate's addresses.
    server = await asyncio.start_server(
        lambda _r, w: w.close(), "127.0.0.1", 0, ssl=server_context(cert, key)
    )
    port = server.sockets[0].getsockname()[1]
    try:
        pinned = ssl.create_default_context(cadata=cert.read_text())
        _, writer = await asyncio.open_connection(
            "127.0.0.1", port, ssl=pinned, server_hostname="127.0.0.1"
        )
        assert writer.get_extra_info("ssl_object").getpeercert(binary_form=True) == der
        writer.close()
    finally:
        server.close()
        await server.wait_closed()
