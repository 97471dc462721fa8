"""Layer: service. Login, logout and who-am-I."""

from __future__ import annotations

import asyncio
import math

from fastapi import APIRouter, Request, Response
from pydantic import BaseModel, Field

from cobot_hmi.service.auth import SESSION_COOKIE
from cobot_hmi.service.deps import ServiceDep, SessionDep, client_address
from cobot_hmi.service.errors import ApiError, unauthorized
from cobot_hmi.service.users import User, UsersError

router = APIRouter(prefix="/api/v1/auth", tags=["auth"])


class Credentials(BaseModel):
    username: str = Field(min_length=1, max_length=64)
    password: str = Field(min_length=1, max_length=1024)


def _user_json(user: User) -> dict[str, str]:
    return {"name": user.name, "role": user.role.label}


@router.post("/login", summary="Log in: a session cookie and a bearer token")
async def login(
    credentials: Credentials, request: Request, response: Response, service: ServiceDep
) -> dict[str, object]:
    # The client address is the connection's peer (or, only from a configured trusted proxy,
    # its X-Forwarded-For: uvicorn's proxy headers, service/server.py).
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
    if user is None:
        service.throttle.failed(user_name, client)
        service.logins["failed"] += 1
        raise unauthorized("wrong user name or password")
    service.throttle.succeeded(user_name, client)
    service.logins["ok"] += 1
    session = service.sessions.create(user)
    response.set_cookie(
        SESSION_COOKIE,
        session.token,
        httponly=True,
        samesite="strict",
        secure=service.settings.cookie_secure,
        path="/",
    )
    return {"user": _user_json(user), "token": session.token}


@router.post("/logout", summary="End the session (and release control if it holds it)")
async def logout(response: Response, service: ServiceDep, session: SessionDep) -> dict[str, object]:
    if session is not None:
        service.sessions.end(session, "logged out")
    response.delete_cookie(SESSION_COOKIE, path="/")
    return {"user": None}


@router.get("/me", summary="The logged-in user, or null")
async def me(session: SessionDep) -> dict[str, object]:
    return {"user": None if session is None else _user_json(session.user)}
