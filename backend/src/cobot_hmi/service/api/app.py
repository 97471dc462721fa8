"""Layer: service. The FastAPI application: routes over a ``Service``, the built frontend at ``/``.

``create_app(service)`` wires the routers; the app's lifespan starts and stops the service, so
``uvicorn`` runs the whole thing. The frontend (``frontend/dist``) is served when it exists:
a file under it by its path, anything else that is not API an ``index.html`` (the single-page
app routes ``/kiosk`` and friends itself), precompressed and cached (``static_files``).
"""

from __future__ import annotations

from collections.abc import AsyncIterator, Callable
from contextlib import AbstractAsyncContextManager, asynccontextmanager
from typing import Final

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response

from cobot_hmi import __version__
from cobot_hmi.service.api import compression, security, static_files
from cobot_hmi.service.api.metrics import HttpCollector, ServiceMetrics
from cobot_hmi.service.api.openapi_extras import openapi_document
from cobot_hmi.service.api.routes import alarms as routes_alarms
from cobot_hmi.service.api.routes import auth as routes_auth
from cobot_hmi.service.api.routes import checkouts as routes_checkouts
from cobot_hmi.service.api.routes import cycles as routes_cycles
from cobot_hmi.service.api.routes import health as routes_health
from cobot_hmi.service.api.routes import history as routes_history
from cobot_hmi.service.api.routes import log as routes_log
from cobot_hmi.service.api.routes import presets as routes_presets
from cobot_hmi.service.api.routes import read as routes_read
from cobot_hmi.service.api.routes import stream as routes_stream
from cobot_hmi.service.api.routes import tags as routes_tags
from cobot_hmi.service.api.routes import write as routes_write
from cobot_hmi.service.errors import ApiError, UnknownRobotError
from cobot_hmi.service.runtime import Service

_API_PREFIXES = ("api/", "healthz", "readyz", "metrics", "docs", "openapi.json", "redoc")


_ROUTES: Final = (
    routes_read,
    routes_auth,
    routes_write,
    routes_log,
    routes_history,
    routes_alarms,
    routes_tags,
    routes_cycles,
    routes_stream,
    routes_checkouts,
    routes_presets,
    routes_health,
)
"""Every route module of the API, in the order the OpenAPI document lists them."""


def create_app(
    service: Service,
    *,
    manage_lifecycle: bool = True,
    on_started: Callable[[], None] | None = None,
) -> FastAPI:
    """The ASGI app. With ``manage_lifecycle`` its lifespan starts and stops ``service``;
    ``on_started`` runs once the service has started (process-wide tuning)."""
    app = FastAPI(
        title="cobot-hmi",
        version=__version__,
        summary="Live frames, writes, control, login and audit for Doosan cobots over "
        "EtherNet/IP class 1. See docs/api.md.",
        lifespan=_lifespan(service, manage_lifecycle, on_started),
        # One component per model (no Foo-Input / Foo-Output pairs): the generated client's
        # names stay the models' names.
        separate_input_output_schemas=False,
    )
    app.state.service = service
    app.add_middleware(routes_stream.TransportAbortMiddleware)
    # The API's answers of 1 kB or more gzipped when the request accepts it (compression.py);
    # inside the security middlewares, so their refusals and headers are untouched.
    app.add_middleware(compression.ApiGZipMiddleware, prefixes=_API_PREFIXES)
    # Body limit, Host/Origin/content-type checks, anonymous write gate, security headers:
    # outside everything else (service/api/security.py).
    policy = security.policy_from_settings(service.settings.web)
    refusals = security.install(app, policy)
    # One Prometheus registry per service (``GET /metrics``); the connection bounds' counters
    # and the TLS context come with the server (``server.uvicorn_config``), after the app.
    app.state.metrics = ServiceMetrics(
        service,
        HttpCollector(
            refusals,
            lambda: getattr(app.state, "connection_counters", None),
            lambda: getattr(app.state, "tls", None),
        ),
    )
    install_error_answers(app)
    for module in _ROUTES:
        app.include_router(module.router)
    static_files.serve_frontend(app, service.settings.web.frontend_path, _API_PREFIXES)
    app.openapi = lambda: openapi_document(app)  # type: ignore[method-assign]
    return app


def _lifespan(
    service: Service, manage_lifecycle: bool, on_started: Callable[[], None] | None
) -> Callable[[FastAPI], AbstractAsyncContextManager[None]]:
    @asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        if manage_lifecycle:
            await service.start()
        if on_started is not None:
            on_started()
        try:
            yield
        finally:
            if manage_lifecycle:
                await service.stop()

    return lifespan


def install_error_answers(app: FastAPI) -> None:
    """The API's refusals as JSON ``{"detail": …}``: its own errors, an unknown robot (404),
    and a request that does not validate (422 with the first reason and the field it names)."""

    @app.exception_handler(ApiError)
    async def api_error(_: Request, error: ApiError) -> Response:
        return JSONResponse({"detail": error.detail}, error.status, headers=error.headers)

    @app.exception_handler(UnknownRobotError)
    async def unknown_robot(_: Request, error: UnknownRobotError) -> Response:
        api = error.to_api_error()
        return JSONResponse({"detail": api.detail}, api.status)

    @app.exception_handler(RequestValidationError)
    async def invalid_request(_: Request, error: RequestValidationError) -> Response:
        first = error.errors()[0] if error.errors() else {}
        location = [str(p) for p in first.get("loc", ()) if p not in ("body", "query", "path")]
        return JSONResponse(
            {
                "detail": {
                    "reason": str(first.get("msg", "invalid request")),
                    "field": ".".join(location) or None,
                }
            },
            422,
        )
