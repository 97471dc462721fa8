"""The built frontend over HTTP: precompressed copies by ``Accept-Encoding``, caching headers.

A small dist is precompressed by the real build step (``frontend/scripts/precompress.mjs``, on
Node) and served by the real service; each answer is decoded by an independent decoder (the
``gzip`` module, the ``brotli`` package) and compared with the original bytes.
"""

from __future__ import annotations

import gzip
import shutil
import subprocess
from pathlib import Path

import brotli
import httpx
import pytest

from cobot_hmi.service.api.static_files import accepted_encodings, choose_encoding
from conftest import free_tcp_port
from service_support import running_service, service_settings

REPO_ROOT = Path(__file__).resolve().parents[2]
PRECOMPRESS = REPO_ROOT / "frontend" / "scripts" / "precompress.mjs"

SCRIPT = ("export function tick(n) { return `plot ${n} of the live panel`; }\n" * 400).encode()
STYLE = (".plot { color: #0072b2; margin: 0 auto; }\n" * 200).encode()
INDEX = b'<!doctype html><title>HMI</title><script type="module" src="/assets/app-Ab12Cd34.js">'
FAVICON = bytes(range(256)) * 8  # not text: never compressed


@pytest.fixture
def dist(tmp_path: Path) -> Path:
    node = shutil.which("node")
    assert node is not None, "Node.js is needed to build the frontend (see docs/getting-started)"
    root = tmp_path / "dist"
    (root / "assets").mkdir(parents=True)
    (root / "index.html").write_bytes(INDEX)
    (root / "assets" / "app-Ab12Cd34.js").write_bytes(SCRIPT)
    (root / "assets" / "app-Ef56Gh78.css").write_bytes(STYLE)
    (root / "favicon.ico").write_bytes(FAVICON)
    subprocess.run([node, str(PRECOMPRESS), str(root)], check=True, capture_output=True)
    return root


async def _raw(client: httpx.AsyncClient, path: str, accept: str) -> tuple[httpx.Response, bytes]:
    """The answer and its body exactly as sent (httpx would otherwise decode it)."""
    async with client.stream("GET", path, headers={"Accept-Encoding": accept}) as answer:
        body = b"".join([chunk async for chunk in answer.aiter_raw()])
    return answer, body


async def test_precompressed_assets_by_accept_encoding(
    dist: Path, robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    assert (dist / "assets" / "app-Ab12Cd34.js.br").is_file()
    assert (dist / "assets" / "app-Ab12Cd34.js.gz").is_file()
    assert not (dist / "favicon.ico.br").exists()
    # No robot answers there: this is about HTTP only.
    settings = service_settings(
        robot_host, free_tcp_port(robot_host), plc_host, tmp_path / "state", frontend_dir=dist
    )
    async with (
        running_service(settings, wait_connected=False) as hmi,
        hmi.client() as client,
    ):
        answer, body = await _raw(client, "/assets/app-Ab12Cd34.js", "gzip, deflate, br, zstd")
        assert answer.status_code == 200
        assert answer.headers["content-encoding"] == "br"
        assert answer.headers["vary"] == "Accept-Encoding"
        assert answer.headers["cache-control"] == "public, max-age=31536000, immutable"
        assert answer.headers["content-type"].startswith(
            ("text/javascript", "application/javascript")
        )
        assert int(answer.headers["content-length"]) == len(body) < len(SCRIPT) // 10
        assert brotli.decompress(body) == SCRIPT

        answer, body = await _raw(client, "/assets/app-Ab12Cd34.js", "gzip")
        assert answer.headers["content-encoding"] == "gzip"
        assert answer.headers["vary"] == "Accept-Encoding"
        assert gzip.decompress(body) == SCRIPT

        # A weight of 0 refuses a coding (RFC 9110 §12.5.3).
        answer, body = await _raw(client, "/assets/app-Ef56Gh78.css", "br;q=0, gzip;q=0.5")
        assert answer.headers["content-encoding"] == "gzip"
        assert answer.headers["content-type"].startswith("text/css")
        assert gzip.decompress(body) == STYLE

        for accept in ("identity", "", "br;q=0, gzip;q=0", "compress"):
            answer, body = await _raw(client, "/assets/app-Ab12Cd34.js", accept)
            assert "content-encoding" not in answer.headers, accept
            assert answer.headers["vary"] == "Accept-Encoding"
            assert body == SCRIPT

        # httpx's own decoding (brotli installed) agrees.
        decoded = await client.get("/assets/app-Ab12Cd34.js", headers={"Accept-Encoding": "br"})
        assert decoded.content == SCRIPT

        # The page itself: revalidated every time, whatever the route.
        for path in ("/", "/kiosk", "/fleet?robot=a", "/index.html"):
            answer, body = await _raw(client, path, "gzip, br")
            assert answer.status_code == 200, path
            assert answer.headers["cache-control"] == "no-cache", path
            assert body == INDEX, path  # under the size worth compressing

        # A file outside assets/ has no content hash in its name: revalidated too.
        answer, body = await _raw(client, "/favicon.ico", "gzip, br")
        assert answer.headers["cache-control"] == "no-cache"
        assert "content-encoding" not in answer.headers
        assert "vary" not in answer.headers
        assert body == FAVICON

        assert (await client.get("/assets/missing-00000000.js")).status_code == 404


def test_accept_encoding_parsing() -> None:
    assert accepted_encodings("gzip, br;q=0.8, *;q=0") == {"gzip": 1.0, "br": 0.8, "*": 0.0}
    assert accepted_encodings(None) == {}
    assert accepted_encodings(" , GZIP ; Q=0.5") == {"gzip": 0.5}
    assert accepted_encodings("br;q=x") == {"br": 0.0}  # unreadable weight: not wanted
    available = ("br", "gzip")
    assert choose_encoding("gzip, br", available) == "br"  # a tie: the smaller coding
    assert choose_encoding("gzip;q=1, br;q=0.9", available) == "gzip"
    assert choose_encoding("*", available) == "br"
    assert choose_encoding("*;q=0.1, br;q=0", available) == "gzip"
    assert choose_encoding("deflate", available) is None
    assert choose_encoding(None, available) is None
    assert choose_encoding("gzip", ()) is None
