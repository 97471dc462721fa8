"""The OPC UA tests' independent client: node-opcua (npm, ``tests/peers``), one node process per
test module driven over stdin/stdout (``peers/opcua_client.js``), and a client certificate.

``make test`` installs the peers (``npm ci`` in tests/peers).
"""

from __future__ import annotations

import asyncio
import itertools
import json
import random
import shutil
import socket
from pathlib import Path
from typing import Any

from asyncua.crypto import cert_gen
from cryptography import x509
from cryptography.hazmat.primitives import serialization
from cryptography.x509.oid import ExtendedKeyUsageOID

PEERS = Path(__file__).parent / "peers"
ROBOTICS_NODESET = PEERS / "node_modules/node-opcua-nodesets/nodesets/Opc.Ua.Robotics.NodeSet2.xml"
CLIENT_URI = "urn:cobot-hmi-tests:node-opcua"
MARK = b"@@opcua "
LINE_BYTES = 64 * 1024 * 1024
"""The longest answer (a browse of the whole DeviceSet is a few MB)."""
ANSWER_S = 60.0
"""How long one request may take before the test fails (a functional bound, never a figure)."""


def listening_port(host: str) -> int:
    """A TCP port free on ``host`` below the kernel's ephemeral range, for a server the test
    starts later: a port from ``free_tcp_port`` is in that range, and the service's own
    outgoing connections from ``host`` (its EtherNet/IP sessions, made before the OPC UA server
    listens) may take it meanwhile."""
    low = int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    while True:
        port = random.randrange(20_000, low)
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
            try:
                probe.bind((host, port))
            except OSError:
                continue
        return port


class PeerError(RuntimeError):
    """node-opcua refused or failed a request; the message is its error."""


class OpcUaPeer:
    """node-opcua's client in a process of its own (see the module docstring)."""

    def __init__(self, process: asyncio.subprocess.Process, pki: Path) -> None:
        self._process = process
        self._ids = itertools.count(1)
        self._lock = asyncio.Lock()
        self.pki = pki

    @classmethod
    async def start(cls, pki: Path) -> OpcUaPeer:
        node = shutil.which("node")
        assert node, "node missing: `make test` needs nodejs"
        assert (PEERS / "node_modules" / "node-opcua").is_dir(), "run `make peers` (npm ci)"
        process = await asyncio.create_subprocess_exec(
            node,
            str(PEERS / "opcua_client.js"),
            cwd=PEERS,
            stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.DEVNULL,
            limit=LINE_BYTES,
        )
        return cls(process, pki)

    async def close(self) -> None:
        assert self._process.stdin is not None
        self._process.stdin.close()
        try:
            await asyncio.wait_for(self._process.wait(), ANSWER_S)
        except TimeoutError:
            self._process.kill()
            await self._process.wait()

    async def request(self, op: str, **arguments: Any) -> Any:
        """One request; its result, or ``PeerError`` with node-opcua's message."""
        stdin, stdout = self._process.stdin, self._process.stdout
        assert stdin is not None and stdout is not None
        async with self._lock:
            identifier = next(self._ids)
            stdin.write((json.dumps({"id": identifier, "op": op, **arguments}) + "\n").encode())
            await stdin.drain()
            while True:
                line = await asyncio.wait_for(stdout.readline(), ANSWER_S)
                assert line, "the node-opcua peer exited"
                if not line.startswith(MARK):  # node-opcua's own messages
                    continue
                answer = json.loads(line[len(MARK) :])
                if answer.get("id") == identifier:
                    break
        if not answer["ok"]:
            raise PeerError(answer["error"])
        return answer["result"]

    async def connect(
        self,
        name: str,
        endpoint: str,
        *,
        mode: str = "None",
        user: tuple[str, str] | None = None,
        certificate: tuple[Path, Path] | None = None,
    ) -> dict[str, str]:
        arguments: dict[str, Any] = {
            "name": name,
            "endpoint": endpoint,
            "mode": mode,
            "pki": str(self.pki),
            "applicationUri": CLIENT_URI,
        }
        if user is not None:
            arguments |= {"user": user[0], "password": user[1]}
        if certificate is not None:
            arguments |= {"cert": str(certificate[0]), "key": str(certificate[1])}
        result: dict[str, str] = await self.request("connect", **arguments)
        return result


def client_certificate(directory: Path) -> tuple[Path, Path]:
    """A client application certificate for ``CLIENT_URI`` and its key, as PEM files."""
    directory.mkdir(parents=True, exist_ok=True)
    key = cert_gen.generate_private_key()
    certificate = cert_gen.generate_self_signed_app_certificate(
        key,
        "cobot-hmi tests",
        {"organizationName": "cobot-hmi tests"},
        [x509.UniformResourceIdentifier(CLIENT_URI), x509.DNSName("localhost")],
        extended=[ExtendedKeyUsageOID.CLIENT_AUTH],
    )
    cert_path, key_path = directory / "client.pem", directory / "client.key"
    cert_path.write_bytes(certificate.public_bytes(serialization.Encoding.PEM))
    key_path.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.TraditionalOpenSSL,
            serialization.NoEncryption(),
        )
    )
    return cert_path, key_path


def trust(certificate: Path, trusted_dir: Path) -> None:
    """Put a client certificate into the server's trust list (DER, as a client's would be)."""
    loaded = x509.load_pem_x509_certificate(certificate.read_bytes())
    trusted_dir.mkdir(parents=True, exist_ok=True)
    (trusted_dir / "tests-client.der").write_bytes(loaded.public_bytes(serialization.Encoding.DER))
