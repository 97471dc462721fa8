"""Layer: emulator (no sockets here). Imports ``cobot_hmi.enip`` and the emulator's own modules.

The target's Connection Manager object (class 0x06, instance 1; CIP Vol 1 §3-5): Forward Open
and Large Forward Open (admission rules, the connection they create), Forward Close, and the
Unconnected Send some originators wrap them in. Every connection path is decoded by
``enip.epath`` whatever the width of its segments and compared by value (class, configuration
instance, connection points, key), never as bytes.

Every refused Forward Open is logged with its general and extended status in words and counted
per status (:meth:`ConnectionManager.refusals`, shown by the control API's ``GET /status``;
docs/emulator.md). docs/protocol.md "Refusals" lists when each status is given.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from cobot_hmi.emulator.connections import ConnectionKind, IoConnection
from cobot_hmi.emulator.counters import TargetCounters
from cobot_hmi.emulator.encap_server import SessionContext
from cobot_hmi.emulator.faults import TargetFaults
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.enip import cip, epath
from cobot_hmi.enip.cip import MessageRouterRequest, MessageRouterResponse, Service
from cobot_hmi.enip.connection_manager import (
    CONNECTION_MANAGER_INSTANCE,
    TRANSPORT_CLASS1_CYCLIC,
    ConnectionFailureReply,
    ConnectionType,
    ForwardCloseReply,
    ForwardOpenReply,
    ForwardOpenRequest,
    decode_forward_close,
    decode_forward_open,
    decode_unconnected_send,
)
from cobot_hmi.enip.cpf import CpfItem, ItemType, Sockaddr, decode_sockaddr, sockaddr_item
from cobot_hmi.enip.errors import EnipError, PathError
from cobot_hmi.enip.status import ExtendedStatus, GeneralStatus, describe

log = logging.getLogger(__name__)

Reply = tuple[MessageRouterResponse, list[CpfItem]]
Route = Callable[[MessageRouterRequest, list[CpfItem], SessionContext], Reply]
"""The Message Router's entry point (``objects.MessageRouter.route``): where the request an
Unconnected Send carries goes."""


class RefusalError(Exception):
    """A Forward Open the target refuses: general status 0x01 with ``extended``."""

    def __init__(self, extended: int, *additional: int) -> None:
        super().__init__(f"extended status 0x{extended:04X}")
        self.extended = extended
        self.additional = additional

    @property
    def words(self) -> tuple[int, ...]:
        return (self.extended, *self.additional)


def admit(
    request: ForwardOpenRequest,
    path: epath.ConnectionPath,
    settings: TargetSettings,
    identity_key_check: Callable[[epath.ElectronicKey], int | None],
    table: list[IoConnection],
) -> ConnectionKind:
    """The kind of connection ``request`` (its connection path decoded: ``path``) opens, or
    :class:`RefusalError` with its extended status."""
    if request.transport != TRANSPORT_CLASS1_CYCLIC:
        raise RefusalError(ExtendedStatus.TRANSPORT_NOT_SUPPORTED)
    if any(conn.triplet == request.triplet for conn in table):
        raise RefusalError(ExtendedStatus.CONNECTION_IN_USE)
    if path.class_id != epath.CLASS_ASSEMBLY or len(path.points) != 2:
        raise RefusalError(ExtendedStatus.INVALID_SEGMENT_IN_PATH)
    if path.key is not None:
        mismatch = identity_key_check(path.key)
        if mismatch is not None:
            raise RefusalError(mismatch)
    o2t_point, t2o_point = path.points
    if path.config_instance != settings.config_instance or t2o_point != settings.t2o_instance:
        raise RefusalError(ExtendedStatus.INVALID_APPLICATION_PATH)
    kinds = {
        settings.o2t_instance: ConnectionKind.OWNER,
        settings.input_only_instance: ConnectionKind.INPUT_ONLY,
        settings.listen_only_instance: ConnectionKind.LISTEN_ONLY,
    }
    kind = kinds.get(o2t_point)
    if kind is None:
        raise RefusalError(ExtendedStatus.INVALID_APPLICATION_PATH)
    if path.config_data:
        raise RefusalError(ExtendedStatus.INVALID_CONFIGURATION_SIZE, 0)
    for rpi_us in (request.o2t_rpi_us, request.t2o_rpi_us):
        if not settings.rpi_min_us <= rpi_us <= settings.rpi_max_us:
            raise RefusalError(ExtendedStatus.RPI_NOT_SUPPORTED)
    if request.timeout_multiplier > 7:
        raise RefusalError(ExtendedStatus.TIMEOUT_MULTIPLIER_NOT_ACCEPTABLE)
    if request.o2t_params.connection_type is not ConnectionType.POINT_TO_POINT:
        raise RefusalError(ExtendedStatus.INVALID_O2T_CONNECTION_TYPE)
    if request.t2o_params.connection_type is not ConnectionType.POINT_TO_POINT:
        # Multicast T→O is not produced by this target: every connection is point-to-point.
        raise RefusalError(ExtendedStatus.INVALID_T2O_CONNECTION_TYPE)
    o2t_size = request.o2t_params.size_bytes
    if kind is ConnectionKind.OWNER:
        if o2t_size != settings.o2t_connection_size:
            raise RefusalError(ExtendedStatus.INVALID_O2T_SIZE, settings.o2t_connection_size)
    elif o2t_size not in settings.heartbeat_sizes:
        raise RefusalError(ExtendedStatus.INVALID_O2T_SIZE, settings.heartbeat_sizes[0])
    if request.t2o_params.size_bytes != settings.t2o_connection_size:
        raise RefusalError(ExtendedStatus.INVALID_T2O_SIZE, settings.t2o_connection_size)
    if kind is ConnectionKind.OWNER and any(c.kind is ConnectionKind.OWNER for c in table):
        raise RefusalError(ExtendedStatus.OWNERSHIP_CONFLICT)
    if kind is ConnectionKind.LISTEN_ONLY and not any(c.produces for c in table):
        raise RefusalError(ExtendedStatus.NON_LISTEN_ONLY_NOT_OPENED)
    if len(table) >= settings.max_connections:
        raise RefusalError(ExtendedStatus.OUT_OF_CONNECTIONS)
    return kind


@dataclass(frozen=True, slots=True)
class RefusalCount:
    """How often Forward Opens were refused with one status, for a status API."""

    general_status: int
    extended_status: int | None
    count: int
    meaning: str


class IoEngine(Protocol):
    """What the Connection Manager needs of the class 1 engine (``io_connections``)."""

    def table(self) -> list[IoConnection]: ...

    def open(
        self,
        kind: ConnectionKind,
        request: ForwardOpenRequest,
        path: epath.ConnectionPath,
        peer: tuple[str, int],
    ) -> IoConnection: ...

    def close(self, conn: IoConnection, reason: str) -> None: ...

    @property
    def udp_port(self) -> int: ...


class ConnectionManager:
    """Class 0x06 instance 1 of the target."""

    def __init__(
        self,
        settings: TargetSettings,
        faults: TargetFaults,
        counters: TargetCounters,
        engine: IoEngine,
    ) -> None:
        self.settings = settings
        self.faults = faults
        self.counters = counters
        self.engine = engine
        self._refusals: dict[tuple[int, int | None], int] = {}

    def refusals(self) -> list[RefusalCount]:
        """Every status a Forward Open was refused with so far, and how often."""
        return [
            RefusalCount(
                general,
                extended,
                count,
                describe(general, () if extended is None else (extended,)),
            )
            for (general, extended), count in sorted(
                self._refusals.items(), key=lambda item: (item[0][0], item[0][1] or 0)
            )
        ]

    def handle(
        self,
        request: MessageRouterRequest,
        path: epath.RequestPath,
        items: list[CpfItem],
        session: SessionContext,
        route: Route,
    ) -> Reply:
        """A request the Message Router found addressed to class 0x06 (in any path width)."""
        if path.instance != CONNECTION_MANAGER_INSTANCE or path.attribute is not None:
            status = (
                GeneralStatus.OBJECT_DOES_NOT_EXIST
                if path.instance != CONNECTION_MANAGER_INSTANCE
                else GeneralStatus.SERVICE_NOT_SUPPORTED
            )
            if request.service in (Service.FORWARD_OPEN, Service.LARGE_FORWARD_OPEN):
                return self._refuse(request, session, None, general=status)
            return MessageRouterResponse(request.service, status), []
        if request.service in (Service.FORWARD_OPEN, Service.LARGE_FORWARD_OPEN):
            return self._forward_open(request, items, session)
        if request.service == Service.FORWARD_CLOSE:
            return self._forward_close(request), []
        if request.service == Service.UNCONNECTED_SEND:
            try:
                send = decode_unconnected_send(request.data)
                inner = cip.decode_request(send.message)
            except EnipError:
                return MessageRouterResponse(
                    request.service,
                    GeneralStatus.CONNECTION_FAILURE,
                    (ExtendedStatus.UNCONNECTED_SEND_PARAMETER_ERROR,),
                ), []
            try:
                route_ports = epath.decode_segments(send.route_path)
            except PathError as error:
                route_ports = None
                detail = str(error)
            else:
                detail = "a route path of port segments only"
            if route_ports is None or any(seg.kind != "port" for seg in route_ports):
                if inner.service in (Service.FORWARD_OPEN, Service.LARGE_FORWARD_OPEN):
                    return self._refuse(
                        request,
                        session,
                        None,
                        general=GeneralStatus.CONNECTION_FAILURE,
                        additional=(ExtendedStatus.INVALID_SEGMENT_IN_PATH,),
                        detail=f"Unconnected Send route path: {detail}",
                    )
                return MessageRouterResponse(
                    request.service,
                    GeneralStatus.CONNECTION_FAILURE,
                    (ExtendedStatus.INVALID_SEGMENT_IN_PATH,),
                ), []
            # The embedded request's reply stands for the Unconnected Send's (CIP Vol 1
            # §3-5.5.2): this target is the end of the route.
            return route(inner, items, session)
        return MessageRouterResponse(request.service, GeneralStatus.SERVICE_NOT_SUPPORTED), []

    # ------------------------------------------------------------------ refusals

    def refuse(
        self, request: MessageRouterRequest, session: SessionContext, status: int, detail: str
    ) -> Reply:
        """A Forward Open that did not reach this object (a request path that does not decode,
        or names another object): refused with ``status``, counted and logged like any other."""
        return self._refuse(request, session, None, general=status, detail=detail)

    def _refuse(
        self,
        request: MessageRouterRequest,
        session: SessionContext,
        fo: ForwardOpenRequest | None,
        *,
        general: int,
        additional: tuple[int, ...] = (),
        detail: str = "",
    ) -> Reply:
        """Refuse a Forward Open: count it under its status, log it in words, answer it (with
        the connection triplet when the request got far enough to have one)."""
        extended = additional[0] if general == GeneralStatus.CONNECTION_FAILURE else None
        key = (general, extended)
        self._refusals[key] = self._refusals.get(key, 0) + 1
        self.counters.forward_open_refusals += 1
        log.warning(
            "Forward Open from %s refused: %s%s",
            session.peer_host,
            describe(general, additional),
            f" ({detail})" if detail else "",
        )
        data = b""
        if fo is not None:
            data = ConnectionFailureReply(
                fo.connection_serial, fo.vendor_id, fo.originator_serial
            ).encode()
        return MessageRouterResponse(request.service, general, additional, data), []

    # ------------------------------------------------------------------ services

    def _forward_open(
        self, request: MessageRouterRequest, items: list[CpfItem], session: SessionContext
    ) -> Reply:
        large = request.service == Service.LARGE_FORWARD_OPEN
        self.counters.forward_opens += 1
        try:
            fo = decode_forward_open(request.data, large=large)
        except EnipError as error:
            return self._refuse(
                request, session, None, general=GeneralStatus.NOT_ENOUGH_DATA, detail=str(error)
            )

        def refuse(refusal: RefusalError, detail: str = "") -> Reply:
            return self._refuse(
                request,
                session,
                fo,
                general=GeneralStatus.CONNECTION_FAILURE,
                additional=refusal.words,
                detail=detail,
            )

        injected = self.faults.refuse_next_forward_open
        if injected is not None:
            self.faults.refuse_next_forward_open = None
            return refuse(RefusalError(injected), "injected by the control API")
        try:
            path = fo.connection_path()
        except PathError as error:
            return refuse(RefusalError(ExtendedStatus.INVALID_SEGMENT_IN_PATH), str(error))
        t2o_port = self.settings.t2o_port_default
        for item in items:
            if item.type_id == ItemType.SOCKADDR_T2O:
                try:
                    t2o_port = decode_sockaddr(item.data).port
                except EnipError as error:
                    return refuse(
                        RefusalError(ExtendedStatus.INVALID_NETWORK_PARAMETER), str(error)
                    )
        identity = self.settings.identity
        try:
            kind = admit(
                fo,
                path,
                self.settings,
                lambda key: key.mismatch(identity),
                self.engine.table(),
            )
        except RefusalError as refusal:
            return refuse(refusal)
        conn = self.engine.open(kind, fo, path, (session.peer_host, t2o_port))
        reply = ForwardOpenReply(
            conn.o2t_id,
            conn.t2o_id,
            fo.connection_serial,
            fo.vendor_id,
            fo.originator_serial,
            fo.o2t_rpi_us,
            fo.t2o_rpi_us,
        )
        # Where O→T goes: our UDP port on the address the originator reached us at.
        o2t_item = sockaddr_item(
            ItemType.SOCKADDR_O2T, Sockaddr(session.local_host, self.engine.udp_port)
        )
        return MessageRouterResponse(request.service, 0, (), reply.encode()), [o2t_item]

    def _forward_close(self, request: MessageRouterRequest) -> MessageRouterResponse:
        self.counters.forward_closes += 1
        try:
            fc = decode_forward_close(request.data)
        except EnipError:
            return MessageRouterResponse(request.service, GeneralStatus.NOT_ENOUGH_DATA)
        failure = ConnectionFailureReply(fc.connection_serial, fc.vendor_id, fc.originator_serial)
        try:
            fc.connection_path()
        except PathError as error:
            log.warning("Forward Close refused: invalid segment in path (%s)", error)
            return MessageRouterResponse(
                request.service,
                GeneralStatus.CONNECTION_FAILURE,
                (ExtendedStatus.INVALID_SEGMENT_IN_PATH,),
                failure.encode(),
            )
        # The connection is the one with the same triplet (CIP Vol 1 §3-5.4); the path only has
        # to be a path.
        for conn in self.engine.table():
            if conn.triplet == fc.triplet:
                self.engine.close(conn, "Forward Close")
                reply = ForwardCloseReply(fc.connection_serial, fc.vendor_id, fc.originator_serial)
                return MessageRouterResponse(request.service, 0, (), reply.encode())
        log.info("Forward Close for no open connection %s", fc.triplet)
        return MessageRouterResponse(
            request.service,
            GeneralStatus.CONNECTION_FAILURE,
            (ExtendedStatus.CONNECTION_NOT_FOUND,),
            failure.encode(),
        )


__all__ = ["ConnectionManager", "RefusalCount", "RefusalError", "admit"]
