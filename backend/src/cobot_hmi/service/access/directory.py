"""Layer: service. Directory login: users and their roles from LDAP / Active Directory (ldap3).

A login binds as the user: their DN is made from a template (``ldap_user_dn``, the name
escaped as an RDN value, RFC 4514) or found by a search with the service account (or
anonymously) under ``ldap_search_base`` with ``ldap_user_filter`` (the name escaped for a
filter, RFC 4515), which must find exactly one entry. A name such as ``*)(uid=*`` or
``admin,ou=x`` is therefore a name nobody has, never a wider filter or another DN. An empty
password is refused before anything is sent (a simple bind with one is an anonymous bind,
RFC 4513 §5.1.2, which many servers accept).

The role comes from the groups ``ldap_group_role`` maps, read at each login: the user is a
member of a group whose entry lists their DN in ``member`` (``groupOfNames``, Active
Directory's ``group``) or ``uniqueMember`` (``groupOfUniqueNames``), or whose DN is in the
user's ``memberOf`` (Active Directory, OpenLDAP's memberof overlay). Several groups: the
highest role. None: refused (``NoRoleError``).

Every call to the directory blocks (ldap3's synchronous strategy, one connection per call,
``ldap_timeout_s`` for connecting and each answer): ``login`` and ``refresh`` run it on a
worker thread, so the event loop never waits on the directory. A directory that cannot be
reached (refused, timed out, TLS failed, the service account refused) is
``DirectoryUnreachableError``; local users are not affected (routes/auth.py asks the users
file first).

While a directory user has a session, their role is read again every ``ldap_role_refresh_s``
(``refresh_loop``, with the service account or anonymously): ``user`` answers the sessions'
question "who is NAME now", so a changed role or a user in no mapped group any more ends the
session at the sessions' next sweep (``access.auth.Sessions``). An unreachable directory keeps
the role last read (a directory outage does not throw operators out mid-shift).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import ssl
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Final

from ldap3 import ANONYMOUS, BASE, NONE, SIMPLE, SUBTREE, Connection, Server, Tls
from ldap3.core.exceptions import LDAPException
from ldap3.utils.conv import escape_filter_chars
from ldap3.utils.dn import escape_rdn

from cobot_hmi.service.access.directory_settings import (
    USER_PLACEHOLDER,
    DirectorySettings,
    normal_dn,
)
from cobot_hmi.service.access.users import Role, User

log = logging.getLogger(__name__)

UNREACHABLE: Final = "directory unreachable"
_SESSION_GRACE_S: Final = 60.0
"""A login's account is kept this long before a refresh may drop it for having no session
(the route creates the session just after the login, and may wait on the audit meanwhile)."""
_INVALID_CREDENTIALS: Final = 49
"""LDAP resultCode invalidCredentials (RFC 4511 §4.1.9)."""


class DirectoryUnreachableError(Exception):
    """The directory could not answer (its address, TLS, a timeout, the service account)."""

    def __init__(self, cause: str) -> None:
        super().__init__(f"{UNREACHABLE}: {cause}")
        self.cause = cause


class NoRoleError(Exception):
    """The user's password is right but none of their groups is mapped to a role."""

    def __init__(self, name: str) -> None:
        super().__init__(
            f"user {name} is in none of the directory groups that give a role here "
            "(ask an administrator to add you to one)"
        )


@dataclass(frozen=True, slots=True)
class DirectoryAccount:
    """A directory user as their last login or refresh found them."""

    user: User
    dn: str
    groups: frozenset[str]
    """The mapped groups they are in (normal DNs, ``directory_settings.normal_dn``)."""


class Directory:
    """The directory of ``settings`` (``ldap_url`` set) and its logged-in users' roles."""

    def __init__(self, settings: DirectorySettings) -> None:
        self.settings = settings
        self._tls = Tls(
            validate=ssl.CERT_REQUIRED,
            ca_certs_file=None if settings.ldap_ca_file is None else str(settings.ldap_ca_file),
        )
        self._accounts: dict[str, DirectoryAccount] = {}
        """By user name: directory users with (possibly) a live session; touched only on the
        event loop's thread."""
        self._logged_in_at: dict[str, float] = {}
        """By user name: ``time.monotonic()`` of their last login."""

    # ----------------------------------------------------------------- on the event loop

    def user(self, name: str) -> User | None:
        """The directory user ``name`` as last read, if they logged in (the sessions' check)."""
        account = self._accounts.get(name)
        return None if account is None else account.user

    async def login(self, name: str, password: str) -> User | None:
        """The user if ``password`` is theirs in the directory (``None``: unknown name or
        wrong password); ``NoRoleError``, ``DirectoryUnreachableError``. On a worker thread."""
        account = await asyncio.to_thread(self.authenticate, name, password)
        if account is None:
            return None
        self._accounts[name] = account
        self._logged_in_at[name] = time.monotonic()
        return account.user

    async def refresh(self, live_names: set[str]) -> None:
        """Read again the role of each directory user in ``live_names`` (users with a live
        session); forget the others."""
        now = time.monotonic()
        for name in list(self._accounts):
            if name not in live_names and now - self._logged_in_at[name] > _SESSION_GRACE_S:
                del self._accounts[name]
                del self._logged_in_at[name]
        for name, account in list(self._accounts.items()):
            try:
                again = await asyncio.to_thread(self.account, name, account.dn)
            except DirectoryUnreachableError as error:
                log.warning("directory: %s's role not read again (%s); kept", name, error)
                continue
            if again is None:
                log.info("directory: %s is in no mapped group any more", name)
                self._accounts.pop(name, None)
                self._logged_in_at.pop(name, None)
            else:
                if again.user.role != account.user.role:
                    log.info("directory: %s's role is now %s", name, again.user.role.label)
                self._accounts[name] = again

    async def refresh_loop(self, live_names: Callable[[], set[str]]) -> None:
        """``refresh`` every ``ldap_role_refresh_s`` (a task of the service)."""
        while True:
            await asyncio.sleep(self.settings.ldap_role_refresh_s)
            await self.refresh(live_names())

    # ----------------------------------------------------------------- blocking (a thread)

    def authenticate(self, name: str, password: str) -> DirectoryAccount | None:
        """Bind as ``name`` with ``password`` and read their role; ``None``: no such user or
        a wrong password. Blocking."""
        if not name or not password:
            return None  # an empty password would be an anonymous bind
        settings = self.settings
        if settings.ldap_user_dn:
            dn = settings.ldap_user_dn.replace(USER_PLACEHOLDER, escape_rdn(name))
        else:
            with self._service_connection() as service:
                found = self._find(service, name)
            if found is None:
                return None
            dn = found
        with self._connection(dn, password) as bound:
            if bound is None:
                return None
            if settings.ldap_bind_dn:  # the service account reads groups, as at a refresh
                account = self.account(name, dn)
            else:
                account = self._account(bound, name, dn)
        if account is None:
            raise NoRoleError(name)
        return account

    def account(self, name: str, dn: str) -> DirectoryAccount | None:
        """``name``'s role read with the service account (or anonymously); ``None``: in no
        mapped group. Blocking."""
        with self._service_connection() as service:
            return self._account(service, name, dn)

    def _find(self, service: Connection, name: str) -> str | None:
        """The DN of the one entry ``ldap_user_filter`` finds for ``name``, or ``None``."""
        user_filter = self.settings.ldap_user_filter.replace(
            USER_PLACEHOLDER, escape_filter_chars(name)
        )
        service.search(
            self.settings.ldap_search_base, user_filter, SUBTREE, attributes=["1.1"], size_limit=2
        )
        _check_answer(service)
        dns = [str(entry["dn"]) for entry in _entries(service)]
        if len(dns) > 1:
            log.warning("directory: %r names more than one entry (%s): refused", name, dns)
            return None
        return dns[0] if dns else None

    def _account(self, connection: Connection, name: str, dn: str) -> DirectoryAccount | None:
        mapped = self.settings.ldap_group_role
        groups: set[str] = set()
        connection.search(dn, "(objectClass=*)", BASE, attributes=["memberOf"])
        _check_answer(connection)
        for entry in _entries(connection):
            attributes = entry.get("attributes")
            member_of = attributes.get("memberOf") if isinstance(attributes, dict) else None
            for group in member_of or []:
                try:
                    groups.add(normal_dn(str(group)))
                except ValueError:
                    continue
        member = escape_filter_chars(dn)
        for group in mapped:
            if group in groups:
                continue
            connection.search(
                group, f"(|(member={member})(uniqueMember={member}))", BASE, attributes=["1.1"]
            )
            _check_answer(connection)
            if _entries(connection):
                groups.add(group)
        mine = frozenset(groups & mapped.keys())
        if not mine:
            return None
        role = max(Role.parse(mapped[group]) for group in mine)
        return DirectoryAccount(User(name, role), dn, mine)

    @contextmanager
    def _service_connection(self) -> Iterator[Connection]:
        """Bound as the service account, or anonymously without one."""
        settings = self.settings
        password = settings.ldap_bind_password.get_secret_value()
        with self._connection(settings.ldap_bind_dn or None, password) as connection:
            if connection is None:
                raise DirectoryUnreachableError("the service account's bind was refused")
            yield connection

    @contextmanager
    def _connection(self, dn: str | None, password: str) -> Iterator[Connection | None]:
        """A connection bound as ``dn`` (``None``: anonymously), ``None`` when the directory
        refuses the credentials; ``DirectoryUnreachableError`` when it cannot be asked."""
        settings = self.settings
        # A Server per connection: ldap3's Server remembers an address that failed as
        # unavailable for minutes (RESET_AVAILABILITY_TIMEOUT), and resolves its name once.
        server = Server(
            settings.ldap_url, tls=self._tls, get_info=NONE, connect_timeout=settings.ldap_timeout_s
        )
        connection = Connection(
            server,
            user=dn,
            password=password if dn else None,
            authentication=SIMPLE if dn else ANONYMOUS,
            receive_timeout=math.ceil(settings.ldap_timeout_s),  # ldap3 packs it as whole s
            raise_exceptions=False,
            read_only=True,
            # Active Directory answers a search from a domain's root with referrals to its other
            # partitions (DomainDnsZones …): never chased, only entries are read.
            auto_referrals=False,
        )
        try:
            try:
                connection.open()
                if settings.ldap_start_tls and not connection.start_tls():
                    raise DirectoryUnreachableError(f"StartTLS refused ({_result(connection)})")
                bound = connection.bind()
            except LDAPException as error:
                raise DirectoryUnreachableError(_why(error)) from None
            if not bound:
                code = connection.result.get("result") if connection.result else None
                if code != _INVALID_CREDENTIALS:
                    log.warning("directory: bind as %s refused (%s)", dn, _result(connection))
                yield None
                return
            try:
                yield connection
            except LDAPException as error:
                raise DirectoryUnreachableError(_why(error)) from None
        finally:
            with contextlib.suppress(LDAPException):  # already gone: nothing to close
                connection.unbind()
            if connection.socket is not None:  # a failed open or TLS leaves ldap3's socket open
                connection.socket.close()


def _entries(connection: Connection) -> list[dict[str, object]]:
    return [r for r in connection.response or [] if r.get("type") == "searchResEntry"]


_ANSWERED: Final = frozenset({0, 4, 32})
"""success, sizeLimitExceeded (two entries are enough to refuse), noSuchObject (no group)."""


def _check_answer(connection: Connection) -> None:
    """``DirectoryUnreachableError`` for an answer that is no answer (busy, unavailable,
    a server-side time limit, insufficient rights): never read as "no such user"."""
    code = connection.result.get("result") if connection.result else None
    if code not in _ANSWERED:
        raise DirectoryUnreachableError(f"a search failed ({_result(connection)})")


def _result(connection: Connection) -> str:
    result = connection.result or {}
    return f"{result.get('description', '?')}: {result.get('message', '')}".rstrip(": ")


def _why(error: LDAPException) -> str:
    """ldap3's reason without the reprs of the tuples it wraps it in."""
    text, before = str(error) or type(error).__name__, ""
    while text != before:
        before = text
        for opening, closing in (("(", ",)"), ("'", "'"), ('"', '"')):
            if len(text) > len(opening + closing) and text.startswith(opening):
                text = text.removeprefix(opening).removesuffix(closing)
    return text.removeprefix("socket ssl wrapping error: ")
