"""Layer: service. The users file: names, roles and salted scrypt password hashes.

A JSON file ``{"users": {"alice": {"role": "operator", "password": "scrypt$…"}}}``, written
atomically (temporary file + rename) with mode 0600. The service re-reads it when its
modification time changes, so ``cobot-hmi users add`` takes effect without a restart. Pure
file I/O; imports nothing of the project.
"""

from __future__ import annotations

import base64
import functools
import hashlib
import hmac
import json
import os
import re
import secrets
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from typing import Final


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
MIN_PASSWORD_CHARS: Final = 8


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

    def _load(self) -> dict[str, tuple[Role, str]]:
        try:
            stat = self.path.stat()
        except FileNotFoundError:
            self._stamp, self._entries = None, {}
            return self._entries
        stamp = (stat.st_mtime_ns, stat.st_size)
        if stamp == self._stamp:
            return self._entries
        try:
            document = json.loads(self.path.read_text(encoding="utf-8"))
            entries: dict[str, tuple[Role, str]] = {}
            for name, entry in document["users"].items():
                entries[name] = (Role.parse(entry["role"]), str(entry["password"]))
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
            # Keep the last good table: a half-edited file must not lock everyone out.
            raise UsersError(f"users file {self.path}: unreadable ({error})") from None
        self._stamp, self._entries = stamp, entries
        return entries

    def users(self) -> list[User]:
        return [User(name, role) for name, (role, _) in sorted(self._load().items())]

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
        self._save(entries)
        return User(name, role)

    def _save(self, entries: dict[str, tuple[Role, str]]) -> None:
        document = {
            "users": {n: {"role": r.label, "password": h} for n, (r, h) in sorted(entries.items())}
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
