"""Layer: service. Login, logout, who-am-I and a person's activity (which alone, with the
API's other changing requests, keeps a session from idling out: ``access.auth``).

A login is checked against the users file first; a name the file does not have is asked of the
directory when one is configured (``access.directory``: a local name is never a directory
user's, so the file's break-glass admin logs in whatever the directory says or whether it
answers). With a directory, every attempt the throttle lets through is audited (action
``login``; ``requested`` says which of the two answered: who the directory let in, or not, and
the local logins beside them); the throttle counts wrong passwords of both.
"""

from __future__ import annotations

import asyncio
import logging
import math
from typing import Final

from fastapi import APIRouter, Request, Response
from pydantic import BaseModel, Field

from cobot_hmi.service.access.auth import SESSION_COOKIE, Session
from cobot_hmi.service.access.directory import (
    UNREACHABLE,
    DirectoryUnreachableError,
    NoRoleError,
)
from cobot_hmi.service.access.users import User, UsersError
from cobot_hmi.service.api.deps import ServiceDep, SessionDep, client_address
from cobot_hmi.service.api.models import LoginAnswer, Me
from cobot_hmi.service.api.models import User as UserModel
from cobot_hmi.service.api.openapi_extras import errors
from cobot_hmi.service.errors import ApiError, unauthorized
from cobot_hmi.service.storage.store import AuditEntry

router = APIRouter(prefix="/api/v1/auth", tags=["auth"])
log = logging.getLogger(__name__)
_LOGIN_ORIGIN: Final = "POST /api/v1/auth/login"
_WRONG: Final = "wrong user name or password"


class Credentials(BaseModel):
    username: str = Field(min_length=1, max_length=64)
    password: str = Field(min_length=1, max_length=1024)


def _user_model(user: User) -> UserModel:
    return UserModel.model_validate({"name": user.name, "role": user.role.label})


@router.post(
    "/login",
    summary="Log in: a session cookie and a bearer token",
    responses=errors(401, 403, 413, 415, 422, 429, 503),
)
async def login(
    credentials: Credentials, request: Request, response: Response, service: ServiceDep
) -> LoginAnswer:
    # The client address is the connection's peer (or, only from a configured trusted proxy,
    # its X-Forwarded-For: uvicorn's proxy headers, service/api/server.py).
    user_name, client = credentials.username, client_address(request)
    wait_s = service.throttle.retry_after_s(user_name, client)
    if wait_s > 0:
        service.logins["throttled"] += 1
        seconds = math.ceil(wait_s)
        error = ApiError(429, f"too many failed logins: try again in {seconds} s")
        error.headers["Retry-After"] = str(seconds)
        raise error
    try:
        # scrypt takes tens of milliseconds and releases the GIL: keep it off the event loop.
        user = await asyncio.to_thread(
            service.users.authenticate, credentials.username, credentials.password
        )
    except UsersError as error:
        raise ApiError(503, str(error)) from None
    source = "local"
    directory = service.directory
    if user is None and directory is not None and service.users.user(user_name) is None:
        source = "directory"
        try:
            user = await directory.login(user_name, credentials.password)
        except DirectoryUnreachableError as error:
            log.warning("login of %r: %s", user_name, error)
            service.logins["unreachable"] += 1
            await _audit_login(
                service, user_name, client, source=source, outcome="unreachable", reason=str(error)
            )
            raise ApiError(503, UNREACHABLE) from None
        except NoRoleError as error:
            service.logins["forbidden"] += 1
            await _audit_login(
                service, user_name, client, source=source, outcome="forbidden", reason=str(error)
            )
            raise ApiError(403, str(error)) from None
    if user is None:
        service.throttle.failed(user_name, client)
        service.logins["failed"] += 1
        await _audit_login(
            service, user_name, client, source=source, outcome="refused", reason=_WRONG
        )
        raise unauthorized(_WRONG)
    service.throttle.succeeded(user_name, client)
    service.logins["ok"] += 1
    await _audit_login(
        service, user_name, client, source=source, outcome="ok", reason=f"role {user.role.label}"
    )
    session = service.sessions.create(user)
    response.set_cookie(
        SESSION_COOKIE,
        session.token,
        httponly=True,
        samesite="strict",
        secure=service.settings.web.cookie_secure or request.url.scheme == "https",
        path="/",
    )
    return LoginAnswer(user=_user_model(user), token=session.token)


async def _audit_login(
    service: ServiceDep, user: str, client: str | None, *, source: str, outcome: str, reason: str
) -> None:
    """One audit row per login attempt when a directory is configured (kept in memory while
    the disk is full). Without one the audit trail stays what it was: writes and control."""
    if service.directory is None:
        return
    entry = AuditEntry(
        user, client, "login", [], None, {"source": source}, outcome, reason, origin=_LOGIN_ORIGIN
    )
    await service.store.keep_audit(entry, happened=outcome == "ok")


@router.post(
    "/logout",
    summary="End the session (and release control if it holds it)",
    responses=errors(403, 415),
    response_model_exclude_unset=True,
)
async def logout(response: Response, service: ServiceDep, session: SessionDep) -> Me:
    if session is not None:
        service.sessions.end(session, "logged out")
    response.delete_cookie(SESSION_COOKIE, path="/")
    return Me(user=None)


def _me(service: ServiceDep, session: Session | None) -> Me:
    if session is None:
        return Me(user=None)
    left_s = service.sessions.expires_in_s(session)
    return Me(
        user=_user_model(session.user),
        idle_timeout_s=None if left_s is None else service.sessions.ttl_s,
        idle_expires_in_s=left_s,
    )


@router.get(
    "/me",
    summary="The logged-in user, or null, and how long before the session idles out (a read: "
    "it never renews the session)",
    response_model_exclude_unset=True,  # no session: {"user": null}, as before
)
async def me(service: ServiceDep, session: SessionDep) -> Me:
    return _me(service, session)


@router.post(
    "/activity",
    summary="Its person acted (a click, a key): the session's idle deadline is renewed. A page "
    "sends it on its person's actions, never on a timer of its own",
    responses=errors(401, 403, 415),
    response_model_exclude_unset=True,
)
async def activity(service: ServiceDep, session: SessionDep) -> Me:
    if session is None:
        raise unauthorized("no session (it expired or ended): log in again")
    return _me(service, session)
