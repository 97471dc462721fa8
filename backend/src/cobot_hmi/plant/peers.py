"""Layer: plant (a door above the service). The other ``plant`` processes whose cells this one's
page shows beside its own (``--peer URL``, repeatable; docs/operations.md "How a plant grows"):
a plant split by Sparkplug group over processes, each following its groups, one page over all.

Each peer's edge nodes are asked for (``GET /api/v1/plant/nodes?local=true``: its own only, so
two processes naming each other never ask in a circle) by a task of its own every
``PEER_POLL_S``, each request bounded by ``PEER_TIMEOUT_S``, and the last answer kept: the
page's ``/nodes`` merges what is kept and never waits for a peer. A peer that does not answer is
said to be down since when (``GET /api/v1/plant/peers``), its cells kept as last answered. The
alarm list and the shift's figures, which depend on the page's range, are asked for when the
page asks, from every peer at once, each bounded by the same timeout; a peer that does not
answer in time is left out of that answer and marked down. A trend of a peer's cell is asked of
that peer (its history holds it).

HTTP with the standard library on worker threads (the plant's runtime has no HTTP client), with
a bearer token when the peers ask for a login (``--plant-peer-token``: a viewer's API token
there).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass, field
from typing import Any, Final

log = logging.getLogger(__name__)

PEER_POLL_S: Final = 0.25
"""As often as the page asks its own process (``NODES_POLL_MS``)."""
PEER_TIMEOUT_S: Final = 1.0
"""One request to a peer, at most (connecting, and each read): a hung peer costs its own task
this, never the page."""
MAX_ANSWER_BYTES: Final = 64 * 1024 * 1024
"""A peer's answer read at most this far (a plant of thousands of robots is a few MB)."""


class PeerError(Exception):
    """A peer did not answer, or not with JSON: the reason in words."""


@dataclass
class PeerState:
    """What this process knows of one peer."""

    url: str
    answering: bool = False
    since_ms: int = field(default_factory=lambda: int(time.time() * 1000))
    """When ``answering`` last changed (or the first ask)."""
    error: str | None = "not asked yet"
    nodes: list[dict[str, Any]] = field(default_factory=list)
    """Its nodes as it last answered (the API's ``NodeModel`` objects)."""
    answered_ms: int = 0

    def answered(self, nodes: list[dict[str, Any]]) -> None:
        if not self.answering:
            self.since_ms = int(time.time() * 1000)
            log.info("plant peer %s answers", self.url)
        self.answering, self.error, self.nodes = True, None, nodes
        self.answered_ms = int(time.time() * 1000)

    def failed(self, reason: str) -> None:
        if self.answering or self.error == "not asked yet":
            self.since_ms = int(time.time() * 1000)
            log.warning("plant peer %s does not answer: %s", self.url, reason)
        self.answering, self.error = False, reason


def _get_json(url: str, token: str, timeout_s: float) -> Any:
    """``url``'s JSON answer (on a worker thread); ``PeerError`` with the reason otherwise."""
    request = urllib.request.Request(url, headers={"Accept": "application/json"})
    if token:
        request.add_header("Authorization", f"Bearer {token}")
    try:
        with urllib.request.urlopen(request, timeout=timeout_s) as answer:
            body = answer.read(MAX_ANSWER_BYTES + 1)
    except urllib.error.HTTPError as error:
        raise PeerError(f"HTTP {error.code}") from None
    except (urllib.error.URLError, OSError, ValueError) as error:
        reason = getattr(error, "reason", error)
        raise PeerError(str(reason) or type(error).__name__) from None
    if len(body) > MAX_ANSWER_BYTES:
        raise PeerError("answer too large")
    try:
        return json.loads(body)
    except ValueError:
        raise PeerError("not JSON") from None


class Peers:
    """The peers of one plant process: ``start`` in the web loop, ``stop`` once."""

    def __init__(self, urls: list[str], token: str = "", timeout_s: float = PEER_TIMEOUT_S) -> None:
        self.peers = [PeerState(url.rstrip("/")) for url in urls]
        self._token = token
        self._timeout_s = timeout_s
        self._tasks: list[asyncio.Task[None]] = []

    async def start(self) -> None:
        self._tasks = [
            asyncio.create_task(self._follow(peer), name=f"plant-peer {peer.url}")
            for peer in self.peers
        ]

    async def stop(self) -> None:
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._tasks = []

    def owner(self, group: str, node: str) -> PeerState | None:
        """The peer that last answered with this node (a trend of it is that peer's)."""
        for peer in self.peers:
            if any(n.get("group") == group and n.get("node") == node for n in peer.nodes):
                return peer
        return None

    async def ask(self, peer: PeerState, path: str, params: dict[str, str]) -> Any:
        """``path`` of one peer (its own part), bounded by the timeout; ``PeerError``."""
        return await self._ask(peer, path, params)

    async def _ask(self, peer: PeerState, path: str, params: dict[str, str]) -> Any:
        query = urllib.parse.urlencode({**params, "local": "true"})
        return await asyncio.to_thread(
            _get_json, f"{peer.url}{path}?{query}", self._token, self._timeout_s
        )

    async def _follow(self, peer: PeerState) -> None:
        while True:
            try:
                nodes = await self._ask(peer, "/api/v1/plant/nodes", {})
                if not isinstance(nodes, list):
                    raise PeerError("not a list of nodes")
                peer.answered([n for n in nodes if isinstance(n, dict)])
            except PeerError as error:
                peer.failed(str(error))
            await asyncio.sleep(PEER_POLL_S)

    async def ask_all(self, path: str, params: dict[str, str]) -> list[tuple[PeerState, Any]]:
        """``path`` of every peer at once (their own part: ``local=true``), each bounded by the
        timeout; the peers that answered, with their answers."""
        if not self.peers:
            return []

        async def one(peer: PeerState) -> tuple[PeerState, Any] | None:
            try:
                return peer, await self._ask(peer, path, params)
            except PeerError as error:
                peer.failed(str(error))
                return None

        found = await asyncio.gather(*(one(peer) for peer in self.peers))
        return [f for f in found if f is not None]
