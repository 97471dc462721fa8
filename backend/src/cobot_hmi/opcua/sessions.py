"""Layer: service (OPC UA). asyncua's sessions, taught which requests are the robots'.

asyncua hands a Write to its attribute service and a Call to its method service without
saying which session sent it. ``RobotSession`` (the class of every client's session, made by
``RobotInternalServer.create_session``) takes the Write values and method calls that belong
to the robots (``writes.CommandWrites``) with its own user, peer and id, answers a write to a
variable nobody may write ``BadNotWritable`` (``writes.access_level_refusal``; asyncua would
say ``BadUserAccessDenied``), and passes the rest on unchanged; it also sets the peer for the
login throttle while a session is activated (``auth.PEER``), whether its channel is signed
while it is created (``security.SECURE_CHANNEL``: a client certificate over SecurityPolicy None
is ignored, Part 4 §5.6.2), and tells ``CommandWrites`` when it closes. Before asyncua creates
or activates a session, the server's ``channel_policy.EndpointGuard`` checks its channel and
identity token (and decrypts the password: ``RobotInternalServer.decrypt_user_token``).

A new subscription is created in phase with the server's monitoring ticks: asyncua starts a
subscription's publishing cycle when it creates it (then every publishing interval on that
grid), so ``CreateSubscription`` is answered at the moment the server's ``subscription_phase``
names (just after a tick has written its values): each cycle then sends the values of the tick
before it at once, instead of up to a whole publishing interval later at a random phase.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from typing import Any

from asyncua import ua
from asyncua.crypto.permission_rules import User, UserRole
from asyncua.server.internal_server import InternalServer
from asyncua.server.internal_session import InternalSession
from asyncua.server.monitored_item_service import MonitoredItemService
from asyncua.server.user_managers import UserManager

from cobot_hmi.opcua.auth import PEER
from cobot_hmi.opcua.channel_policy import EndpointGuard
from cobot_hmi.opcua.security import SECURE_CHANNEL
from cobot_hmi.opcua.writes import Caller, CommandWrites, access_level_refusal

log = logging.getLogger(__name__)

_ANONYMOUS = User(role=UserRole.Anonymous)


def _delete_all_monitored_items(service: MonitoredItemService) -> None:
    """Every monitored item of a subscription deleted (its data-change callbacks, its event
    and data-change indexes), in one pass: what asyncua's own does item by item, each looking
    through every item's callback handle for its own (quadratic: a historian's 17 000 items,
    deleted when its subscription expired or its session closed, held the server's thread and
    the GIL for tens of seconds)."""
    for handle in service._monitored_datachange:
        service.aspace.delete_datachange_callback(handle)
    service._monitored_datachange.clear()
    service._monitored_events.clear()
    service._monitored_items.clear()


MonitoredItemService.delete_all_monitored_items = _delete_all_monitored_items


class RobotInternalServer(InternalServer):
    """asyncua's internal server whose client sessions are ``RobotSession``s."""

    def __init__(self, user_manager: UserManager | Any, guard: EndpointGuard) -> None:
        super().__init__(user_manager=user_manager)
        self.guard = guard
        """The server's own checks of channels, sessions and identity tokens."""
        self.routes: CommandWrites | None = None
        """Set once the robots' nodes exist (before the server listens)."""
        self.subscription_phase: Callable[[], float] | None = None
        """Seconds until a new subscription's publishing cycle should start (``server``)."""
        self.freshen: Callable[[list[ua.NodeId]], Awaitable[None]] | None = None
        """Brings the values of these nodes' robots up to date (``server``): before a Read
        and before new monitored items take their first value."""
        self._closing: set[asyncio.Task[None]] = set()

    def create_session(
        self, name: str, user: User = _ANONYMOUS, external: bool = False
    ) -> InternalSession:
        if not external:
            return super().create_session(name, user, external)
        return RobotSession(self, name, user)

    def channel_is_signed(self) -> bool:
        """Whether the current request came over a Sign or SignAndEncrypt channel; a channel
        that is not one of the endpoints is refused here (``EndpointGuard``)."""
        policy = self.guard.check_session_channel().security_policy
        return bool(policy.Mode != ua.MessageSecurityMode.None_)

    def decrypt_user_token(self, isession: Any, token: ua.UserNameIdentityToken) -> tuple[str, str]:
        """The user name and password, the password as its token policy says it must come
        (``EndpointGuard.password``: asyncua would take it in clear or encrypted alike)."""
        return token.UserName, self.guard.password(token, isession.nonce, self.private_key)

    def session_closed(self, user: User) -> None:
        routes = self.routes
        if routes is None:
            return
        task = asyncio.get_running_loop().create_task(routes.closed(user))
        self._closing.add(task)
        task.add_done_callback(self._closing.discard)


class RobotSession(InternalSession):
    """A client's session (see the module docstring)."""

    def __init__(self, server: RobotInternalServer, name: str, user: User) -> None:
        super().__init__(
            server, server.aspace, server.subscription_service, name, user=user, external=True
        )
        self._server = server

    def _caller(self) -> Caller:
        return Caller(self.user, str(self.name), self.session_id.to_string())

    async def create_session(
        self, params: ua.CreateSessionParameters, sockname: tuple[str, int] | None = None
    ) -> ua.CreateSessionResult:
        token = SECURE_CHANNEL.set(self._server.channel_is_signed())
        try:
            return await super().create_session(params, sockname=sockname)
        finally:
            SECURE_CHANNEL.reset(token)

    def activate_session(
        self, params: ua.ActivateSessionParameters, peer_certificate: bytes | None
    ) -> ua.ActivateSessionResult:
        token = PEER.set(str(self.name))
        try:
            self._server.guard.token_policy(params.UserIdentityToken)  # channel and token policy
            return super().activate_session(params, peer_certificate)
        finally:
            PEER.reset(token)

    async def create_subscription(
        self,
        params: ua.CreateSubscriptionParameters,
        callback: Callable[..., Any],
        request_callback: Callable[..., Any] | None = None,
    ) -> ua.CreateSubscriptionResult:
        phase = self._server.subscription_phase
        if phase is not None:
            await asyncio.sleep(phase())
        return await super().create_subscription(params, callback, request_callback)

    async def read(self, params: ua.ReadParameters) -> list[ua.DataValue]:
        freshen = self._server.freshen
        if freshen is not None:
            await freshen([item.NodeId for item in params.NodesToRead])
        values: list[ua.DataValue] = await super().read(params)
        return values

    async def create_monitored_items(
        self, params: ua.CreateMonitoredItemsParameters
    ) -> list[ua.MonitoredItemCreateResult]:
        freshen = self._server.freshen
        if freshen is not None:
            await freshen([item.ItemToMonitor.NodeId for item in params.ItemsToCreate])
        results: list[ua.MonitoredItemCreateResult] = await super().create_monitored_items(params)
        return results

    async def browse(self, params: ua.BrowseParameters) -> list[ua.BrowseResult]:
        """asyncua's Browse, each reference type's subtypes found once per request: asyncua
        walks the reference type tree again for every reference of every node browsed with
        ``IncludeSubtypes`` (a historian browsing 32 robots' 17 000 variables kept the server's
        thread busy for minutes)."""
        view = self.iserver.view_service
        walk = view._get_sub_ref
        found: dict[ua.NodeId, frozenset[ua.NodeId]] = {}

        def subtypes(reference_type: ua.NodeId) -> frozenset[ua.NodeId]:
            known = found.get(reference_type)
            if known is None:
                known = found[reference_type] = frozenset(walk(reference_type))
            return known

        view._get_sub_ref = subtypes  # this request only: the tree may grow between two
        try:
            results: list[ua.BrowseResult] = view.browse(params)
        finally:
            del view._get_sub_ref
        return results

    async def write(self, params: ua.WriteParameters) -> list[ua.StatusCode]:
        routes = self._server.routes
        values = params.NodesToWrite
        mine = [i for i, v in enumerate(values) if routes is not None and routes.owns_write(v)]
        results: list[ua.StatusCode | None] = [None] * len(values)
        if mine and routes is not None:
            statuses = await routes.write(self._caller(), [values[i] for i in mine])
            for position, status in zip(mine, statuses, strict=True):
                results[position] = status
        for position, value in enumerate(values):  # read-only for everyone: BadNotWritable
            if results[position] is None:
                results[position] = access_level_refusal(self._server.aspace, value)
        others = [i for i in range(len(values)) if results[i] is None]
        if others:
            rest = ua.WriteParameters(NodesToWrite=[values[i] for i in others])
            for position, status in zip(others, await super().write(rest), strict=True):
                results[position] = status
        return [
            r if r is not None else ua.StatusCode(ua.StatusCodes.BadInternalError) for r in results
        ]

    async def call(self, params: list[ua.CallMethodRequest]) -> list[ua.CallMethodResult]:
        routes = self._server.routes
        results = []
        for request in params:
            if routes is not None and routes.owns_call(request):
                results.append(await routes.call(self._caller(), request))
            else:
                results.extend(await super().call([request]))
        return results

    async def close_session(self, delete_subs: bool = True) -> None:
        await super().close_session(delete_subs)
        self._server.session_closed(self.user)
