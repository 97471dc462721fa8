"""Layer: service. Login sessions (cookie or bearer token), their expiry, and login throttling.

Sessions live in memory: a restart logs everyone out, which also drops control (no session
outlives the process that could release it). Imports only ``users`` of the service package.
"""

from __future__ import annotations

import math
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final

from cobot_hmi.service.users import API_TOKEN_PREFIX, User

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
    """Tokens → sessions. ``on_end(session, reason)`` runs when one ends (logout or expiry).

    ``resolve_token`` (the users file's ``user_for_token``) recognises long-lived API tokens
    (``users.API_TOKEN_PREFIX``): each live one has one session, which never idles out and
    ends as soon as the token is revoked or expires (checked on every use).
    """

    def __init__(
        self,
        ttl_s: float,
        on_end: Callable[[Session, str], None],
        resolve_token: Callable[[str], User | None] | None = None,
    ) -> None:
        self.ttl_s = ttl_s
        self._on_end = on_end
        self._resolve_token = resolve_token
        self._by_token: dict[str, Session] = {}
        self._api: dict[str, Session] = {}
        """API token → its session."""

    def __len__(self) -> int:
        return len(self._by_token)

    def _api_session(self, token: str) -> Session | None:
        assert self._resolve_token is not None
        user = self._resolve_token(token)
        session = self._api.get(token)
        if user is None:
            if session is not None:
                del self._api[token]
                self._on_end(session, "API token revoked or expired")
            return None
        if session is None or session.user != user:
            if session is not None:  # its role changed: a new session
                self._on_end(session, "API token changed")
            session = Session(token, user, time.time(), math.inf)
            self._api[token] = session
        return session

    def create(self, user: User) -> Session:
        token = secrets.token_urlsafe(32)
        session = Session(token, user, time.time(), time.monotonic() + self.ttl_s)
        self._by_token[token] = session
        return session

    def get(self, token: str | None) -> Session | None:
        """The live session of ``token`` (its idle deadline renewed), or ``None``."""
        if not token:
            return None
        if self._resolve_token is not None and token.startswith(API_TOKEN_PREFIX):
            return self._api_session(token)
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
        elif self._api.get(session.token) is session:
            del self._api[session.token]
            self._on_end(session, reason)

    def sweep(self) -> int:
        """End every expired session and every revoked or expired API token's session (so
        control is released on time); how many ended."""
        now = time.monotonic()
        expired = [s for s in self._by_token.values() if now >= s.expires_at_mono]
        for session in expired:
            self.end(session, "session expired")
        ended = len(expired)
        for token in list(self._api):
            if self._api_session(token) is None:
                ended += 1
        return ended


class LoginThrottle:
    """Slows down password guessing with two budgets, each doubling its wait per failure.

    - Per client address: after ``free_attempts`` failures from an address (whatever the user
      names), its next attempt must wait 1 s, then 2 s, 4 s … up to ``max_delay_s``. This is
      what holds a guesser back.
    - Per user name: after ``free_attempts`` failures for a name (from any address), attempts
      for it wait 1 s, 2 s … but never more than ``user_max_delay_s``, which is short. A
      guesser failing for ``alice`` from one address therefore cannot lock alice out: from
      her own (fresh) address she waits at most ``user_max_delay_s``, while the guesser's
      address waits ever longer.

    Attempts during a wait are refused without checking the password (HTTP 429), so sending
    them in parallel gains nothing and they do not count. A success clears the user name's
    count (never the address's: a guesser's own account must not reset its address).
    """

    _FORGET_AFTER_S: Final = 3600.0
    _MAX_KEYS: Final = 10_000

    def __init__(
        self, free_attempts: int, max_delay_s: float, user_max_delay_s: float | None = None
    ) -> None:
        self.free_attempts = free_attempts
        self.max_delay_s = max_delay_s
        self.user_max_delay_s = max_delay_s if user_max_delay_s is None else user_max_delay_s
        self._failures: dict[tuple[str, str], tuple[int, float, float]] = {}
        """(kind, key) → (count, last failure, next allowed), on ``time.monotonic()``."""

    @staticmethod
    def _keys(user: str, client: str | None) -> tuple[tuple[str, str], ...]:
        return (("user", user), ("client", client or "?"))

    def retry_after_s(self, user: str, client: str | None) -> float:
        """Seconds until an attempt for ``user`` from ``client`` is allowed (0: now)."""
        now = time.monotonic()
        wait = 0.0
        for key in self._keys(user, client):
            entry = self._failures.get(key)
            if entry is not None:
                wait = max(wait, entry[2] - now)
        return wait

    def failed(self, user: str, client: str | None) -> None:
        now = time.monotonic()
        if len(self._failures) >= self._MAX_KEYS:
            self._forget(now)
        for key in self._keys(user, client):
            limit = self.user_max_delay_s if key[0] == "user" else self.max_delay_s
            count = self._failures.get(key, (0, 0.0, 0.0))[0] + 1
            delay = 0.0
            if count >= self.free_attempts:
                delay = min(2.0 ** min(count - self.free_attempts, 62), limit)
            self._failures[key] = (count, now, now + delay)

    def succeeded(self, user: str, client: str | None) -> None:
        self._failures.pop(("user", user), None)

    def _forget(self, now: float) -> None:
        old = [k for k, (_, last, _) in self._failures.items() if now - last > self._FORGET_AFTER_S]
        for key in old:
            del self._failures[key]
        if len(self._failures) >= self._MAX_KEYS:  # still full: drop the oldest half
            by_age = sorted(self._failures, key=lambda k: self._failures[k][1])
            for key in by_age[: len(by_age) // 2]:
                del self._failures[key]
