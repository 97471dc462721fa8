"""Layer: service. FastAPI dependencies: the service, the robot a path names, the caller's
session, role gates.

A session comes from ``Authorization: Bearer <token>`` or the ``cobot_session`` cookie (the
WebSocket also accepts ``?token=``, since browsers cannot set headers on it). A robot comes from
the ``{name}`` of ``/api/v1/robots/{name}/…`` (404 naming the known ones when unknown); the
deprecated single-robot paths get the first robot of the settings.
"""

from __future__ import annotations

from typing import Annotated, Final

from fastapi import Depends, Path, Query, Request
from starlette.requests import HTTPConnection

from cobot_hmi.service.access.auth import SESSION_COOKIE, Session
from cobot_hmi.service.access.users import Role
from cobot_hmi.service.api.models import ROBOT_NAME_PATTERN
from cobot_hmi.service.errors import UnknownRobotError, forbidden, unauthorized
from cobot_hmi.service.robots.robot import RobotRuntime
from cobot_hmi.service.runtime import Service
from cobot_hmi.service.writes.pipeline import Writer


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


_READS: Final = frozenset({"GET", "HEAD", "OPTIONS"})
"""Methods that never renew a session: reading is not a person's action."""


async def current_session(request: Request) -> Session | None:
    """The request's session; a changing request (a person's action: a write, an
    acknowledgement, taking control, ``POST /api/v1/auth/activity``) renews its idle deadline,
    a read never does (``access.auth``: the page's own polling must not keep it alive)."""
    renew = request.method not in _READS
    return get_service(request).sessions.get(session_token(request), renew=renew)


async def _service(connection: HTTPConnection) -> Service:
    # async: FastAPI runs plain ``def`` dependencies in a worker thread; all of these only
    # touch the service's in-memory state and belong on the event loop.
    return get_service(connection)


ServiceDep = Annotated[Service, Depends(_service)]
SessionDep = Annotated[Session | None, Depends(current_session)]


# The name's pattern is documented, not enforced: any unknown name, well-formed or not, is the
# same 404 naming the known robots.
_NAME_SCHEMA = {"pattern": ROBOT_NAME_PATTERN}


async def robot_from_path(
    service: ServiceDep,
    name: Annotated[
        str, Path(description="the robot's name from the settings", json_schema_extra=_NAME_SCHEMA)
    ],
) -> RobotRuntime:
    try:
        return service.robot(name)
    except UnknownRobotError as error:
        raise error.to_api_error("name") from None


async def default_robot(service: ServiceDep) -> RobotRuntime:
    """The first robot of the settings: what the deprecated single-robot paths answer for."""
    return service.default_robot


async def robot_filter(
    service: ServiceDep,
    robot: Annotated[
        str | None,
        Query(description="only this robot's rows", json_schema_extra=_NAME_SCHEMA),
    ] = None,
) -> str | None:
    """``?robot=``: a known robot's name (404 naming the known ones otherwise) or ``None``."""
    if robot is not None:
        try:
            service.robot(robot)
        except UnknownRobotError as error:
            raise error.to_api_error("robot") from None
    return robot


RobotDep = Annotated[RobotRuntime, Depends(robot_from_path)]
DefaultRobotDep = Annotated[RobotRuntime, Depends(default_robot)]
RobotFilterDep = Annotated[str | None, Depends(robot_filter)]


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
    if service.settings.web.view_requires_login:
        return require(Role.VIEWER, session)
    return session


async def operator(session: SessionDep) -> Session:
    return require(Role.OPERATOR, session)


ViewerDep = Annotated[Session | None, Depends(viewer_gate)]
OperatorDep = Annotated[Session, Depends(operator)]


def client_address(connection: HTTPConnection) -> str | None:
    return connection.client.host if connection.client is not None else None


async def writer(request: Request, session: SessionDep) -> Writer:
    """Who is writing, for the write pipeline (authorization happens there, audited)."""
    return Writer.from_session(session, client_address(request))


WriterDep = Annotated[Writer, Depends(writer)]
