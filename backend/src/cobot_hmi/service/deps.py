"""Layer: service. FastAPI dependencies: the service, the caller's session, role gates.

A session comes from ``Authorization: Bearer <token>`` or the ``cobot_session`` cookie (the
WebSocket also accepts ``?token=``, since browsers cannot set headers on it).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request
from starlette.requests import HTTPConnection

from cobot_hmi.service.auth import SESSION_COOKIE, Session
from cobot_hmi.service.errors import forbidden, unauthorized
from cobot_hmi.service.runtime import Service
from cobot_hmi.service.users import Role


def get_service(connection: HTTPConnection) -> Service:
    service: Service = connection.app.state.service
    return service


def session_token(connection: HTTPConnection) -> str | None:
    header = connection.headers.get("authorization", "")
    scheme, _, token = header.partition(" ")
    if scheme.lower() == "bearer" and token.strip():
        return token.strip()
    cookie = connection.cookies.get(SESSION_COOKIE)
    if cookie:
        return cookie
    if connection.scope["type"] == "websocket":  # a URL token would end up in HTTP logs
        return connection.query_params.get("token") or None
    return None


async def current_session(request: Request) -> Session | None:
    return get_service(request).sessions.get(session_token(request))


async def _service(connection: HTTPConnection) -> Service:
    # async: FastAPI runs plain ``def`` dependencies in a worker thread; all of these only
    # touch the service's in-memory state and belong on the event loop.
    return get_service(connection)


ServiceDep = Annotated[Service, Depends(_service)]
SessionDep = Annotated[Session | None, Depends(current_session)]


def require(role: Role, session: Session | None) -> Session:
    """The session if its role is at least ``role``; 401 / 403 with a reason otherwise."""
    if session is None:
        raise unauthorized(f"login required ({role.label} role)")
    if session.user.role < role:
        raise forbidden(
            f"this needs the {role.label} role; {session.user.name} is {session.user.role.label}"
        )
    return session


async def viewer_gate(service: ServiceDep, session: SessionDep) -> Session | None:
    """Reading is open unless ``view_requires_login`` is set."""
    if service.settings.view_requires_login:
        return require(Role.VIEWER, session)
    return session


async def operator(session: SessionDep) -> Session:
    return require(Role.OPERATOR, session)


ViewerDep = Annotated[Session | None, Depends(viewer_gate)]
OperatorDep = Annotated[Session, Depends(operator)]


def client_address(connection: HTTPConnection) -> str | None:
    return connection.client.host if connection.client is not None else None
