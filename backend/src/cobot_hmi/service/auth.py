"""Layer: service. Login sessions (cookie or bearer token), their expiry, and login throttling.

Sessions live in memory: a restart logs everyone out, which also drops control (no session
outlives the process that could release it). Imports only ``users`` of the service package.
"""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final

from cobot_hmi.service.users import User

SESSION_COOKIE: Final = "cobot_session"


@dataclass(slots=True)
class Session:
    token: str
    user: User
    created_at: float
    """Epoch seconds."""
    expires_at_mono: float
    """``time.monotonic()`` deadline; pushed back by each use (idle expiry)."""
    id: str = field(default_factory=lambda: secrets.token_hex(8))
    """Public handle (never the token) for logs and control ownership."""


class Sessions:
    """Tokens → sessions. ``on_end(session, reason)`` runs when one ends (logout or expiry)."""

    def __init__(self, ttl_s: float, on_end: Callable[[Session, str], None]) -> None:
        self.ttl_s = ttl_s
        self._on_end = on_end
        self._by_token: dict[str, Session] = {}

    def __len__(self) -> int:
        return len(self._by_token)

    def create(self, user: User) -> Session:
        token = secrets.token_urlsafe(32)
        session = Session(token, user, time.time(), time.monotonic() + self.ttl_s)
        self._by_token[token] = session
        return session

    def get(self, token: str | None) -> Session | None:
        """The live session of ``token`` (its idle deadline renewed), or ``None``."""
        if not token:
            return None
        session = self._by_token.get(token)
        if session is None:
            return None
        now = time.monotonic()
        if now >= session.expires_at_mono:
            self.end(session, "session expired")
            return None
        session.expires_at_mono = now + self.ttl_s
        return session

    def end(self, session: Session, reason: str) -> None:
        if self._by_token.pop(session.token, None) is not None:
            self._on_end(session, reason)

    def sweep(self) -> int:
        """End every expired session (so control is released on time); how many ended."""
        now = time.monotonic()
        expired = [s for s in self._by_token.values() if now >= s.expires_at_mono]
        for session in expired:
            self.end(session, "session expired")
        return len(expired)


class LoginThrottle:
    """Slows down guessing: after ``free_attempts`` failures for a user name or a client
    address, the next attempt must wait 1 s, then 2 s, 4 s … up to ``max_delay_s``.

    Attempts during the wait are refused without checking the password (HTTP 429), so a
    guesser gains nothing by sending them in parallel. A success clears the user name's count.
    """

    _FORGET_AFTER_S: Final = 3600.0
    _MAX_KEYS: Final = 10_000

    def __init__(self, free_attempts: int, max_delay_s: float) -> None:
        self.free_attempts = free_attempts
        self.max_delay_s = max_delay_s
        self._failures: dict[str, tuple[int, float, float]] = {}  # key → (count, last, next_ok)

    def retry_after_s(self, keys: tuple[str, ...]) -> float:
        """Seconds until an attempt for these keys is allowed (0: now)."""
        now = time.monotonic()
        wait = 0.0
        for key in keys:
            entry = self._failures.get(key)
            if entry is not None:
                wait = max(wait, entry[2] - now)
        return wait

    def failed(self, keys: tuple[str, ...]) -> None:
        now = time.monotonic()
        if len(self._failures) >= self._MAX_KEYS:
            self._forget(now)
        for key in keys:
            count = self._failures.get(key, (0, 0.0, 0.0))[0] + 1
            delay = 0.0
            if count >= self.free_attempts:
                delay = min(2.0 ** (count - self.free_attempts), self.max_delay_s)
            self._failures[key] = (count, now, now + delay)

    def succeeded(self, keys: tuple[str, ...]) -> None:
        for key in keys:
            self._failures.pop(key, None)

    def _forget(self, now: float) -> None:
        old = [k for k, (_, last, _) in self._failures.items() if now - last > self._FORGET_AFTER_S]
        for key in old:
            del self._failures[key]
        if len(self._failures) >= self._MAX_KEYS:  # still full: drop the oldest half
            by_age = sorted(self._failures, key=lambda k: self._failures[k][1])
            for key in by_age[: len(by_age) // 2]:
                del self._failures[key]
