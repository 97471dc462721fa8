"""Layer: service. What ``/openapi.json`` says beyond the routes' own models: every error status a
route can answer with its schema, the non-JSON content types, and the WebSocket messages.

``errors(401, 404)`` gives a route's ``responses``; ``openapi_document(app)`` is the whole
document with the WebSocket messages (``service.api.models.StreamMessage``) and the hand-read PATCH
body (``CommandPatch``) added to the components, since no route declares them as its own.
Imports only ``service.api.models``.
"""

from __future__ import annotations

import json
from typing import Any, Final

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from prometheus_client.exposition import CONTENT_TYPE_PLAIN_0_0_4
from pydantic import TypeAdapter

from cobot_hmi.service.api.models import ApiErrorResponse, CommandPatch, StreamMessage

_WHY: Final = {
    400: "the request cannot be read",
    401: "login required (or the session expired)",
    403: "the role is too low, or the request is not same-origin",
    404: "no robot of that name (the answer names the known ones)",
    409: "not now: not connected, input-only mode, or control is someone else's",
    413: "the body is larger than the service accepts",
    415: "a body that is not application/json",
    422: "invalid request: the answer names the field; nothing was applied",
    429: "too many attempts: wait as Retry-After says",
    503: (
        "unavailable: not ready or not healthy, the users file unreadable, or (a write, a "
        "control change) the audit trail cannot be written (a full disk): nothing was done"
    ),
    504: "the robot did not confirm in time; the answer has what it reports",
}


def _error_answer(status: int) -> dict[str, Any]:
    return {
        "description": _WHY[status],
        "content": {
            "application/json": {"schema": {"$ref": "#/components/schemas/ApiErrorResponse"}}
        },
    }


def errors(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """``responses`` for a route: each status with the error envelope's schema."""
    return {status: {"model": ApiErrorResponse, "description": _WHY[status]} for status in statuses}


READ: Final = (401, 404)
"""A read of one robot: login when viewing needs it, an unknown robot."""
WRITE: Final = (401, 403, 404, 409, 413, 415, 422, 429, 503, 504)
"""A write through the pipeline: every refusal it and the hardening in front of it give."""
CONTROL: Final = (401, 403, 404, 409, 413, 415, 429, 503)
LOG: Final = (401, 403, 404, 422)

CSV_RESPONSE: Final[dict[str, Any]] = {
    "text/csv": {
        "schema": {
            "type": "string",
            "description": "a header row, then one row per item; nested values as JSON text",
        }
    }
}
PROMETHEUS_CONTENT_TYPE: Final = CONTENT_TYPE_PLAIN_0_0_4
"""The text format 0.0.4 that ``prometheus_client.generate_latest`` writes (``/metrics``)."""

_REF_TEMPLATE: Final = "#/components/schemas/{model}"


def openapi_document(app: FastAPI) -> dict[str, Any]:
    """The app's OpenAPI document, with the WebSocket messages in its components (cached)."""
    if app.openapi_schema is not None:
        return app.openapi_schema
    document = get_openapi(
        title=app.title,
        version=app.version,
        summary=app.summary,
        description=app.description,
        routes=app.routes,
    )
    schemas = document.setdefault("components", {}).setdefault("schemas", {})
    stream = TypeAdapter(StreamMessage).json_schema(ref_template=_REF_TEMPLATE)
    for name, schema in stream.pop("$defs", {}).items():
        schemas.setdefault(name, schema)
    stream["description"] = (
        "One message of WS /api/v1/robots/{name}/stream (JSON text), told apart by `type`."
    )
    schemas["StreamMessage"] = stream
    # The PATCH body is read by hand (so a malformed one is audited); its model documents it.
    patch = CommandPatch.model_json_schema(ref_template=_REF_TEMPLATE)
    for name, schema in patch.pop("$defs", {}).items():
        schemas.setdefault(name, schema)
    schemas["CommandPatch"] = patch
    _own_validation_errors(document)
    for operations in document.get("paths", {}).values():
        for operation in operations.values():
            # The allowed-hosts check answers any route 400 for a foreign Host header.
            operation["responses"].setdefault("400", _error_answer(400))
    app.openapi_schema = document
    return document


_FASTAPI_422: Final = "#/components/schemas/HTTPValidationError"


def _own_validation_errors(document: dict[str, Any]) -> None:
    """FastAPI documents its own 422 shape (``HTTPValidationError``, whose ``input`` has an empty
    schema); this service answers 422 as every other error (``app.invalid_request``). Where a
    route can answer 422 at all (a query or a body to check) it gets the error envelope; where
    only a path string can be wrong (an unknown robot is a 404), the 422 goes."""
    envelope = {"$ref": "#/components/schemas/ApiErrorResponse"}
    for operations in document.get("paths", {}).values():
        for operation in operations.values():
            responses = operation.get("responses", {})
            answer = responses.get("422")
            if answer is None:
                continue
            schema = answer.get("content", {}).get("application/json", {}).get("schema", {})
            if schema.get("$ref") != _FASTAPI_422:
                continue
            checked = operation.get("requestBody") is not None or any(
                p.get("in") == "query" for p in operation.get("parameters", ())
            )
            if checked:
                answer["description"] = _WHY[422]
                answer["content"] = {"application/json": {"schema": envelope}}
            else:
                del responses["422"]
    if _FASTAPI_422 not in json.dumps(document.get("paths", {})):  # nothing refers to them now
        schemas = document.get("components", {}).get("schemas", {})
        schemas.pop("HTTPValidationError", None)
        schemas.pop("ValidationError", None)
