"""Layer: service. Login sessions (cookie or bearer token), their expiry, and login throttling.

Sessions live in memory: a restart logs everyone out, which also drops control (no session
outlives the process that could release it). Imports only ``users`` of the service package.

A login session idles out ``ttl_s`` after its person's last action: only what a person does
renews it (``get(..., renew=True)``: the API's changing requests, among them
``POST /api/v1/auth/activity``, which a page sends on its person's clicks and keys). Reading
never renews it: a page that polls, a stream that reconnects, a script that reads keep the
idle clock running (``api/deps.py`` decides from the request's method, not from anything the
client claims).
"""

from __future__ import annotations

import logging
import math
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final

from cobot_hmi.service.access.users import API_TOKEN_PREFIX, User

SESSION_COOKIE: Final = "cobot_session"

log = logging.getLogger(__name__)

SessionWatcher = Callable[[str], None]
"""Told the reason once, when its session ends (``Sessions.watch``)."""


@dataclass(slots=True)
class Session:
    token: str
    user: User
    created_at: float
    """Epoch seconds."""
    expires_at_mono: float
    """``time.monotonic()`` deadline; pushed back by each of its person's actions (idle
    expiry), never by a read."""
    id: str = field(default_factory=lambda: secrets.token_hex(8))
    """Public handle (never the token) for logs and control ownership."""


class Sessions:
    """Tokens → sessions. ``on_end(session, reason)`` runs when one ends (logout, expiry,
    revocation), then each of its watchers (``watch``: its open WebSockets, which close).

    ``resolve_token`` (the users file's ``user_for_token``) recognises long-lived API tokens
    (``users.API_TOKEN_PREFIX``): each live one has one session, which never idles out and
    ends as soon as the token is revoked or expires (checked on every use and every
    ``sweep``). ``resolve_user`` (the users file's ``user``) is a login's user as the file has
    it now: a session whose user was removed or given another role ends the same way (its
    rights were those of the user it logged in as).
    """

    def __init__(
        self,
        ttl_s: float,
        on_end: Callable[[Session, str], None],
        resolve_token: Callable[[str], User | None] | None = None,
        resolve_user: Callable[[str], User | None] | None = None,
    ) -> None:
        self.ttl_s = ttl_s
        self._on_end = on_end
        self._resolve_token = resolve_token
        self._resolve_user = resolve_user
        self._by_token: dict[str, Session] = {}
        self._api: dict[str, Session] = {}
        """API token → its session."""
        self._watchers: dict[str, dict[int, SessionWatcher]] = {}
        """Session id → its watchers, by a handle of each."""
        self._next_handle = 0

    def __len__(self) -> int:
        return len(self._by_token)

    def user_names(self) -> set[str]:
        """The users with a live login session (whose directory roles are read again)."""
        return {session.user.name for session in self._by_token.values()}

    def live(self, session: Session) -> bool:
        """Whether ``session`` has not ended (without renewing its idle deadline)."""
        return (
            self._by_token.get(session.token) is session or self._api.get(session.token) is session
        )

    def watch(self, session: Session, watcher: SessionWatcher) -> Callable[[], None]:
        """Call ``watcher(reason)`` once when ``session`` ends (at once if it has ended
        already); the function that stops watching (idempotent)."""
        if not self.live(session):
            watcher("session ended")
            return lambda: None
        self._next_handle += 1
        handle = self._next_handle
        self._watchers.setdefault(session.id, {})[handle] = watcher

        def unwatch() -> None:
            watchers = self._watchers.get(session.id)
            if watchers is not None:
                watchers.pop(handle, None)
                if not watchers:
                    del self._watchers[session.id]

        return unwatch

    def _ended(self, session: Session, reason: str) -> None:
        self._on_end(session, reason)
        for watcher in self._watchers.pop(session.id, {}).values():
            try:
                watcher(reason)
            except Exception:  # one watcher's bug must not keep the others open
                log.exception("a watcher of session %s failed", session.id)

    def _user_changed(self, session: Session) -> str | None:
        """Why a login session's user no longer has its rights (removed, another role), or
        ``None``."""
        if self._resolve_user is None:
            return None
        user = self._resolve_user(session.user.name)
        if user is None:
            return f"user {session.user.name} removed"
        if user.role != session.user.role:
            return f"user {user.name}'s role changed to {user.role.label}"
        return None

    def _api_session(self, token: str) -> Session | None:
        assert self._resolve_token is not None
        user = self._resolve_token(token)
        session = self._api.get(token)
        if user is None:
            if session is not None:
                del self._api[token]
                self._ended(session, "API token revoked or expired")
            return None
        if session is None or session.user != user:
            if session is not None:  # its role changed: a new session
                del self._api[token]
                self._ended(session, "API token changed")
            session = Session(token, user, time.time(), math.inf)
            self._api[token] = session
        return session

    def create(self, user: User) -> Session:
        token = secrets.token_urlsafe(32)
        session = Session(token, user, time.time(), time.monotonic() + self.ttl_s)
        self._by_token[token] = session
        return session

    def expires_in_s(self, session: Session) -> float | None:
        """Seconds until ``session`` idles out (``None``: an API token's, which never does)."""
        if math.isinf(session.expires_at_mono):
            return None
        return max(0.0, session.expires_at_mono - time.monotonic())

    def get(self, token: str | None, *, renew: bool = False) -> Session | None:
        """The live session of ``token``, or ``None``; ``renew``: a person acted with it, its
        idle deadline moves a whole ``ttl_s`` past now (a read never renews it)."""
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
        changed = self._user_changed(session)
        if changed is not None:
            self.end(session, changed)
            return None
        if renew:
            session.expires_at_mono = now + self.ttl_s
        return session

    def end(self, session: Session, reason: str) -> None:
        if self._by_token.get(session.token) is session:
            del self._by_token[session.token]
            self._ended(session, reason)
        elif self._api.get(session.token) is session:
            del self._api[session.token]
            self._ended(session, reason)

    def sweep(self) -> int:
        """End every expired session, every session whose user was removed or given another
        role, and every revoked or expired API token's session (so control is released and
        WebSockets close on time); how many ended."""
        now = time.monotonic()
        ending = []
        for session in self._by_token.values():
            reason = (
                "session expired" if now >= session.expires_at_mono else self._user_changed(session)
            )
            if reason is not None:
                ending.append((session, reason))
        for session, reason in ending:
            self.end(session, reason)
        ended = len(ending)
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
