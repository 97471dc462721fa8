"""Layer: emulator (no I/O here). Imports ``cobot_hmi.enip`` and the emulator's own modules.

The target's Message Router (CIP Vol 1 §2-4): every explicit request's path is decoded once by
``enip.epath`` (any segment width: ``20 06 24 01`` and ``21 00 06 00 25 00 01 00`` name the same
object) and the request goes to the object its class names: the Identity object
(``identity``), the Assembly object (``assembly``) or the Connection Manager
(``connection_manager``). A path that does not decode gets general status 0x04, an unknown
class 0x05; nothing here raises for a bad request ("never a dropped socket").
"""

from __future__ import annotations

from cobot_hmi.emulator.assembly import AssemblyObject
from cobot_hmi.emulator.connection_manager import ConnectionManager, Reply
from cobot_hmi.emulator.encap_server import SessionContext
from cobot_hmi.emulator.identity import handle_identity_request
from cobot_hmi.emulator.replies import reply
from cobot_hmi.enip import epath
from cobot_hmi.enip.cip import MessageRouterRequest, Service
from cobot_hmi.enip.cpf import CpfItem
from cobot_hmi.enip.errors import PathError
from cobot_hmi.enip.identity import IdentityInfo
from cobot_hmi.enip.status import GeneralStatus


class MessageRouter:
    """Routes explicit requests to the target's objects by decoded class."""

    def __init__(
        self,
        identity: IdentityInfo,
        assembly: AssemblyObject,
        connection_manager: ConnectionManager,
    ) -> None:
        self.identity = identity
        self.assembly = assembly
        self.connection_manager = connection_manager

    def route(
        self, request: MessageRouterRequest, items: list[CpfItem], session: SessionContext
    ) -> Reply:
        """The response to one request, and any CPF items to add to the reply."""
        try:
            path = epath.decode_request_path(request.path)
        except PathError as error:
            return self._unrouted(request, session, GeneralStatus.PATH_SEGMENT_ERROR, str(error))
        if path.class_id == epath.CLASS_CONNECTION_MANAGER:
            return self.connection_manager.handle(request, path, items, session, self.route)
        if path.class_id == epath.CLASS_ASSEMBLY:
            return self.assembly.handle(request, path), []
        if path.class_id == epath.CLASS_IDENTITY:
            return handle_identity_request(request, path, self.identity), []
        return self._unrouted(
            request, session, GeneralStatus.PATH_DESTINATION_UNKNOWN, f"class 0x{path.class_id:02X}"
        )

    def _unrouted(
        self, request: MessageRouterRequest, session: SessionContext, status: int, detail: str
    ) -> Reply:
        """A request no object takes; a Forward Open's service code makes it a refused Forward
        Open (counted and logged as one) whatever object it was sent to."""
        if request.service in (Service.FORWARD_OPEN, Service.LARGE_FORWARD_OPEN):
            return self.connection_manager.refuse(request, session, status, detail)
        return reply(request, status), []


__all__ = ["MessageRouter"]
