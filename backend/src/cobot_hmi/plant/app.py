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
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import Any, Final

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, RedirectResponse, Response

from cobot_hmi import __version__
from cobot_hmi.plant import routes as plant_routes
from cobot_hmi.plant.peers import Peers
from cobot_hmi.plant.runtime import PlantRuntime
from cobot_hmi.service.api import security, static_files
from cobot_hmi.service.api.routes import auth as routes_auth
from cobot_hmi.service.errors import ApiError

_API_PREFIXES = ("api/", "healthz", "docs", "openapi.json", "redoc")
PLANT_PAGE: Final = "/plant"
"""Where ``/`` leads: the frontend's plant face (``frontend/src/plant``)."""


def create_plant_app(runtime: PlantRuntime) -> FastAPI:
    peers = Peers(runtime.settings.plant.plant_peers, runtime.settings.plant.plant_peer_token)

    @asynccontextmanager
    async def lifespan(_: FastAPI) -> AsyncIterator[None]:
        await runtime.start()
        await peers.start()
        try:
            yield
        finally:
            await peers.stop()
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
    app.state.plant_peers = peers  # the other plant processes its page shows (plant/peers.py)
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

    @app.get("/", include_in_schema=False)
    async def plant_page() -> Response:
        # The built frontend is the cell's too: its plant page is the face at /plant.
        return RedirectResponse(PLANT_PAGE, 307)

    app.include_router(routes_auth.router)
    app.include_router(plant_routes.router)
    static_files.serve_frontend(app, runtime.settings.web.frontend_path, _API_PREFIXES)
    return app


def plant_openapi_document() -> dict[str, Any]:
    """The plant app's document as ``/openapi.json`` serves it, built without starting anything
    (``cobot-hmi openapi --plant``; the frontend's ``generated/plantApi.ts`` is made from it)."""
    from cobot_hmi.plant.plant_settings import PlantSettings

    with TemporaryDirectory(prefix="cobot-hmi-plant-openapi-") as state:
        settings = PlantSettings.from_keys(
            state_dir=Path(state), mqtt_urls=["mqtt://127.0.0.1:1883"]
        )
        return create_plant_app(PlantRuntime(settings)).openapi()
