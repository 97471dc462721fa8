"""Layer: service. The users file: names, roles, salted scrypt password hashes, API tokens.

A JSON file ``{"format_version": 2, "users": {"alice": {"role": "operator", "password":
"scrypt$…"}}, "tokens": {"kiosk-hall": {"role": "viewer", "sha256": "…", "created": t,
"expires": t | null}}}``, written atomically (temporary file + rename) with mode 0600. The
service re-reads it when its modification time changes, so ``cobot-hmi users add`` (or
``token``, ``revoke``) takes effect without a restart.

API tokens are long-lived bearer tokens for kiosks and scripts (``cobot-hmi users token``):
``chmi_`` and 43 random URL-safe characters (256 bits), shown once; the file keeps only their
SHA-256 (a random 256-bit secret needs no slow hash: nothing can be guessed from its digest).
A token acts as the pseudo-user ``token:NAME`` with its own role.

``format_version`` (``stored_format``): version 1, written before the file carried one, has
the same shape and is read as it is (and written as version 2 at the next change); a newer
version is refused by name, the last good table kept. Pure file I/O; imports only
``stored_format`` of the project.
"""

from __future__ import annotations

import base64
import contextlib
import functools
import hashlib
import hmac
import json
import os
import re
import secrets
import time
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from typing import Final

from cobot_hmi.stored_format import StoredFormat


class Role(IntEnum):
    """Ordered: a higher role may do everything a lower one may."""

    VIEWER = 0
    OPERATOR = 1
    ADMIN = 2

    @property
    def label(self) -> str:
        return self.name.lower()

    @classmethod
    def parse(cls, text: str) -> Role:
        try:
            return cls[text.upper()]
        except KeyError:
            names = ", ".join(r.label for r in cls)
            raise UsersError(f"unknown role {text!r} (one of {names})") from None


class UsersError(ValueError):
    """A bad users file, user name, role or password."""


# scrypt cost: n=2^14, r=8, p=1 is the interactive-login setting of the scrypt paper (~16 MiB,
# tens of milliseconds per check), stored with each hash so it can be raised later.
_SCRYPT_N: Final = 1 << 14
_SCRYPT_R: Final = 8
_SCRYPT_P: Final = 1
_SALT_BYTES: Final = 16
_KEY_BYTES: Final = 32
_NAME_PATTERN: Final = re.compile(r"^[A-Za-z0-9_.@-]{1,64}$")
USERS_FORMAT: Final = StoredFormat("users file", 2)
MIN_PASSWORD_CHARS: Final = 8
API_TOKEN_PREFIX: Final = "chmi_"
TOKEN_USER_PREFIX: Final = "token:"
"""A token's pseudo-user is ``token:NAME``: ':' is in no user name, so never a real user's."""


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def hash_password(password: str, *, salt: bytes | None = None) -> str:
    """``scrypt$n$r$p$salt$key`` (base64) for ``password`` with a fresh random salt."""
    salt = salt if salt is not None else secrets.token_bytes(_SALT_BYTES)
    key = hashlib.scrypt(
        password.encode("utf-8"),
        salt=salt,
        n=_SCRYPT_N,
        r=_SCRYPT_R,
        p=_SCRYPT_P,
        dklen=_KEY_BYTES,
        maxmem=64 * 1024 * 1024,
    )
    return f"scrypt${_SCRYPT_N}${_SCRYPT_R}${_SCRYPT_P}${_b64(salt)}${_b64(key)}"


def verify_password(password: str, stored: str) -> bool:
    """Whether ``password`` matches ``stored``; a malformed hash never matches."""
    try:
        scheme, n, r, p, salt, key = stored.split("$")
        if scheme != "scrypt":
            return False
        expected = base64.b64decode(key, validate=True)
        actual = hashlib.scrypt(
            password.encode("utf-8"),
            salt=base64.b64decode(salt, validate=True),
            n=int(n),
            r=int(r),
            p=int(p),
            dklen=len(expected),
            maxmem=64 * 1024 * 1024,
        )
    except (ValueError, TypeError):
        return False
    return hmac.compare_digest(actual, expected)


@functools.cache
def _dummy_hash() -> str:
    return hash_password("no such user", salt=bytes(_SALT_BYTES))


@dataclass(frozen=True, slots=True)
class User:
    name: str
    role: Role


@dataclass(frozen=True, slots=True)
class ApiToken:
    """A long-lived bearer token as the users file keeps it (never the token itself)."""

    name: str
    role: Role
    sha256: str
    created: float
    """Epoch seconds."""
    expires: float | None
    """Epoch seconds, or ``None``: until revoked."""

    def expired(self, now: float) -> bool:
        return self.expires is not None and now >= self.expires


def token_digest(token: str) -> str:
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


def check_name(name: str) -> str:
    if not _NAME_PATTERN.fullmatch(name):
        raise UsersError(f"user name {name!r}: 1–64 letters, digits, '_', '.', '@' or '-'")
    return name


class UsersFile:
    """The users file at ``path``, re-read whenever it changes on disk."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._stamp: tuple[int, int] | None = None
        self._entries: dict[str, tuple[Role, str]] = {}
        self._tokens: dict[str, ApiToken] = {}
        """By name."""
        self._by_digest: dict[str, ApiToken] = {}

    def _load(self) -> dict[str, tuple[Role, str]]:
        try:
            stat = self.path.stat()
        except FileNotFoundError:
            self._stamp, self._entries, self._tokens, self._by_digest = None, {}, {}, {}
            return self._entries
        stamp = (stat.st_mtime_ns, stat.st_size)
        if stamp == self._stamp:
            return self._entries
        try:
            document = json.loads(self.path.read_text(encoding="utf-8"))
            # FormatVersionError is a ValueError: refused below, the last good table kept.
            USERS_FORMAT.read_version(document.get("format_version"), self.path)
            entries: dict[str, tuple[Role, str]] = {}
            for name, entry in document["users"].items():
                entries[name] = (Role.parse(entry["role"]), str(entry["password"]))
            tokens: dict[str, ApiToken] = {}
            for name, entry in document.get("tokens", {}).items():
                expires = entry.get("expires")
                tokens[name] = ApiToken(
                    name,
                    Role.parse(entry["role"]),
                    str(entry["sha256"]),
                    float(entry.get("created", 0.0)),
                    None if expires is None else float(expires),
                )
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
            # Keep the last good table: a half-edited file must not lock everyone out.
            raise UsersError(f"users file {self.path}: unreadable ({error})") from None
        self._stamp, self._entries, self._tokens = stamp, entries, tokens
        self._by_digest = {t.sha256: t for t in tokens.values()}
        return entries

    def users(self) -> list[User]:
        return [User(name, role) for name, (role, _) in sorted(self._load().items())]

    def user(self, name: str) -> User | None:
        """The user called ``name`` as the file has it now (``None``: not in it), so a login
        session can end when its user is removed or given another role. An unreadable file
        keeps the last good table, as ``authenticate`` does."""
        with contextlib.suppress(UsersError):
            self._load()
        entry = self._entries.get(name)
        return None if entry is None else User(name, entry[0])

    def authenticate(self, name: str, password: str) -> User | None:
        """The user if ``password`` is theirs. An unknown name costs the same scrypt work."""
        try:
            entry = self._load().get(name)
        except UsersError:
            entry = self._entries.get(name)
        if entry is None:
            verify_password(password, _dummy_hash())
            return None
        role, stored = entry
        return User(name, role) if verify_password(password, stored) else None

    def add(self, name: str, role: Role, password: str, *, replace: bool = True) -> User:
        """Add ``name`` (or, with ``replace``, set its role and password) and save the file."""
        check_name(name)
        if len(password) < MIN_PASSWORD_CHARS:
            raise UsersError(f"password: at least {MIN_PASSWORD_CHARS} characters")
        entries = dict(self._load())
        if name in entries and not replace:
            raise UsersError(f"user {name!r} exists already")
        entries[name] = (role, hash_password(password))
        self._save(entries, self._tokens)
        return User(name, role)

    # ----------------------------------------------------------------- API tokens

    def tokens(self) -> list[ApiToken]:
        self._load()
        return [self._tokens[name] for name in sorted(self._tokens)]

    def add_token(
        self, name: str, role: Role, *, expires_in_s: float | None, now: float | None = None
    ) -> str:
        """A new token ``name`` (replacing one of that name); the token, shown only now."""
        check_name(name)
        if expires_in_s is not None and not expires_in_s > 0:
            raise UsersError("a token's lifetime must be positive")
        entries = self._load()
        now = time.time() if now is None else now
        token = API_TOKEN_PREFIX + secrets.token_urlsafe(32)
        expires = None if expires_in_s is None else now + expires_in_s
        tokens = dict(self._tokens)
        tokens[name] = ApiToken(name, role, token_digest(token), now, expires)
        self._save(entries, tokens)
        return token

    def revoke_token(self, name: str) -> None:
        entries = self._load()
        if name not in self._tokens:
            raise UsersError(f"no token named {name!r}")
        tokens = {n: t for n, t in self._tokens.items() if n != name}
        self._save(entries, tokens)

    def user_for_token(self, token: str) -> User | None:
        """The pseudo-user of a live API token (``token:NAME``), or ``None``."""
        if not token.startswith(API_TOKEN_PREFIX):
            return None
        with contextlib.suppress(UsersError):  # unreadable: the last good table stands
            self._load()
        entry = self._by_digest.get(token_digest(token))
        if entry is None or entry.expired(time.time()):
            return None
        return User(TOKEN_USER_PREFIX + entry.name, entry.role)

    # ----------------------------------------------------------------- saving

    def _save(self, entries: dict[str, tuple[Role, str]], tokens: dict[str, ApiToken]) -> None:
        document: dict[str, object] = {
            "format_version": USERS_FORMAT.version,
            "users": {n: {"role": r.label, "password": h} for n, (r, h) in sorted(entries.items())},
        }
        if tokens:
            document["tokens"] = {
                t.name: {
                    "role": t.role.label,
                    "sha256": t.sha256,
                    "created": t.created,
                    "expires": t.expires,
                }
                for t in sorted(tokens.values(), key=lambda t: t.name)
            }
        self.path.parent.mkdir(parents=True, exist_ok=True)
        temporary = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w", encoding="utf-8") as file:
            json.dump(document, file, indent=2)
            file.write("\n")
            file.flush()
            os.fsync(file.fileno())
        os.replace(temporary, self.path)
        self._stamp = None


def generate_password() -> str:
    """A random password for generated accounts (the demo's operator)."""
    return secrets.token_urlsafe(12)
