"""Layer: plant (a door above the service). The plant's web app: the service's security
middlewares (body limit, Host and Origin checks, anonymous write gate, security headers) and its
auth routes (login, logout, who-am-I, activity: the same users file, roles, directory and
sessions as ``serve``), the plant's own routes, ``/healthz`` and the built frontend at ``/``.
Its lifespan starts and stops the ``PlantRuntime``. Served by the service's ``uvicorn_config``
(TLS, HTTP bounds), as ``serve`` is.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response

from cobot_hmi import __version__
from cobot_hmi.plant import routes as plant_routes
from cobot_hmi.plant.runtime import PlantRuntime
from cobot_hmi.service.api import security, static_files
from cobot_hmi.service.api.routes import auth as routes_auth
from cobot_hmi.service.errors import ApiError

_API_PREFIXES = ("api/", "healthz", "docs", "openapi.json", "redoc")


def create_plant_app(runtime: PlantRuntime) -> FastAPI:
    @asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        await runtime.start()
        try:
            yield
        finally:
            await runtime.stop()

    app = FastAPI(
        title="cobot-hmi plant",
        version=__version__,
        summary="Every cell of the plant, as a Sparkplug 3.0 host application. See docs/api.md "
        '"The plant".',
        lifespan=lifespan,
        separate_input_output_schemas=False,
    )
    # The auth routes and the viewer gate read ``app.state.service``: the runtime has the login
    # parts they use (users, sessions, throttle, logins, directory, store, settings).
    app.state.service = runtime
    security.install(app, security.policy_from_settings(runtime.settings.web))

    @app.exception_handler(ApiError)
    async def api_error(_: Request, error: ApiError) -> Response:
        return JSONResponse({"detail": error.detail}, error.status, headers=error.headers)

    @app.exception_handler(RequestValidationError)
    async def invalid_request(_: Request, error: RequestValidationError) -> Response:
        first = error.errors()[0] if error.errors() else {}
        location = [str(p) for p in first.get("loc", ()) if p not in ("body", "query", "path")]
        reason = str(first.get("msg", "invalid request"))
        return JSONResponse(
            {"detail": {"reason": reason, "field": ".".join(location) or None}}, 422
        )

    @app.get("/healthz", summary="Whether the plant holds a broker connection")
    async def healthz() -> Response:
        broker = runtime.client.connected_url
        if broker is None:
            return JSONResponse({"status": "unhealthy", "problems": ["no broker connection"]}, 503)
        return JSONResponse({"status": "ok", "broker": broker})

    app.include_router(routes_auth.router)
    app.include_router(plant_routes.router)
    static_files.serve_frontend(app, runtime.settings.web.frontend_path, _API_PREFIXES)
    return app
