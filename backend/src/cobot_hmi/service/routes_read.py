"""Layer: service. Read-only routes: layout, frame, status, command, health, metrics."""

from __future__ import annotations

import functools
import time
from importlib import resources

import orjson
from fastapi import APIRouter, Response
from fastapi.responses import JSONResponse

from cobot_hmi.codec import command_to_json, dumps, frame_to_json
from cobot_hmi.scanner.originator import ConnectionState
from cobot_hmi.service.deps import ServiceDep, ViewerDep
from cobot_hmi.service.metrics import render_metrics

router = APIRouter()


class OrjsonResponse(JSONResponse):
    """JSON through the codec's ``dumps``: tuples as arrays, NaN/inf as null."""

    def render(self, content: object) -> bytes:
        return dumps(content)


@functools.cache
def _layout_bytes() -> bytes:
    return resources.files("cobot_hmi.generated").joinpath("layout.json").read_bytes()


@router.get("/api/v1/layout", tags=["read"], summary="The layout document")
async def get_layout(_: ViewerDep) -> Response:
    return Response(_layout_bytes(), media_type="application/json")


@router.get("/api/v1/frame", tags=["read"], summary="The latest decoded frame")
async def get_frame(service: ServiceDep, _: ViewerDep) -> OrjsonResponse:
    latest = service.hub.latest
    if latest is None:
        return OrjsonResponse({"frame": None, "received_at": None, "age_s": None, "stale": True})
    received_at, frame = latest[1], latest[2]
    age_s = max(0.0, time.time() - received_at)
    stale = (
        age_s * 1000 > service.settings.stale_after_ms
        or service.link.state is not ConnectionState.CONNECTED
    )
    return OrjsonResponse(
        {
            "frame": frame_to_json(frame),
            "received_at": received_at,
            "age_s": age_s,
            "stale": stale,
        }
    )


@router.get("/api/v1/status", tags=["read"], summary="Connection state, counters and control")
async def get_status(service: ServiceDep, _: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse(
        {"connection": await service.connection_status(), "control": service.control.status()}
    )


@router.get("/api/v1/command", tags=["read"], summary="The O→T image being sent, run or idle")
async def get_command(service: ServiceDep, _: ViewerDep) -> OrjsonResponse:
    return OrjsonResponse({"image": command_to_json(service.link.command), "run": service.link.run})


@router.get("/healthz", tags=["health"], summary="The process serves")
async def healthz() -> dict[str, bool]:
    return {"ok": True}


@router.get("/readyz", tags=["health"], summary="Connected to the robot")
async def readyz(service: ServiceDep) -> Response:
    state = service.link.state
    if state is ConnectionState.CONNECTED:
        return Response(orjson.dumps({"ready": True}), media_type="application/json")
    reason = service.link.reason
    text = f"{state.value}{': ' + reason if reason else ''}"
    return Response(
        orjson.dumps({"ready": False, "reason": text}),
        status_code=503,
        media_type="application/json",
    )


@router.get("/metrics", tags=["health"], summary="Prometheus metrics")
async def metrics(service: ServiceDep) -> Response:
    text = render_metrics(service, await service.link.stats())
    return Response(text, media_type="text/plain; version=0.0.4; charset=utf-8")
