"""Layer: service (OPC UA). Who a session is: the service's users, and what each may ask.

- A session logs in with a user name and password of the service's users file
  (``ServiceFeed.authenticate``: the same hashes, roles and throttle rules as the HTTP login).
  Its asyncua user carries the service's ``User`` and a control ``Session`` of its own, so
  taking control, writing and the audit trail know the OPC UA session apart from every other.
- An anonymous session is accepted only where the service lets anonymous readers read (its
  ``view_requires_login`` off); it reads, browses and subscribes, never writes nor calls.
- X.509 user tokens are not offered.
- ``Permissions``: every read and subscription service for an activated session; nobody adds
  or deletes nodes or references over the wire (asyncua's admin role is never given).
"""

from __future__ import annotations

import contextvars
from dataclasses import dataclass
from typing import Any, Final

from asyncua import ua
from asyncua.crypto.permission_rules import USER_TYPES, PermissionRuleset, User, UserRole

from cobot_hmi.opcua.feed import ServiceFeed, Session
from cobot_hmi.opcua.feed import User as Account

PEER: Final[contextvars.ContextVar[str]] = contextvars.ContextVar("opcua_peer", default="")
"""The address of the client whose session is being activated (``sessions`` sets it)."""


@dataclass
class OpcUaUser(User):
    """An asyncua user that is one of the service's users, with its control session."""

    account: Account | None = None
    session: Session | None = None


class UserManager:
    """asyncua's user manager: see the module docstring."""

    def __init__(self, feed: ServiceFeed) -> None:
        self._feed = feed
        self.anonymous_sessions = 0
        self.logins = 0

    def get_user(
        self,
        iserver: Any,
        username: str | None = None,
        password: str | None = None,
        certificate: Any = None,
    ) -> User | None:
        # ``certificate`` is the secure channel's client certificate for every token type (an
        # X.509 user token is never accepted: not offered, asyncua refuses it before this).
        if username is None:
            if not self._feed.anonymous_reads:
                return None
            self.anonymous_sessions += 1
            return User(role=UserRole.Anonymous)
        account = self._feed.authenticate(username, password or "", PEER.get() or "opc.tcp")
        if account is None:
            return None
        self.logins += 1
        return OpcUaUser(
            role=UserRole.User,
            name=account.name,
            account=account,
            session=self._feed.session_for(account),
        )


class Permissions(PermissionRuleset):
    """Session services for every activated session; node management for nobody."""

    def __init__(self) -> None:
        self._allowed = frozenset(ua.NodeId(identifier) for identifier in USER_TYPES)

    def check_validity(self, user: User, action_type_id: ua.NodeId, body: Any) -> bool:
        return action_type_id in self._allowed
