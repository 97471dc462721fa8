"""The API's contract as ``/openapi.json`` states it: complete enough to generate a client (no
empty schema anywhere, every status a route answers with its schema, the CSV and Prometheus
content types, index keys as patterns, the WebSocket messages in the components), the frame
model built from the layout, and the committed copy (``docs/openapi.json``) fresh."""

from __future__ import annotations

import functools
import re
from typing import Any

import orjson
import pytest
from pydantic import ValidationError

from cobot_hmi.cli import main as cli_main
from cobot_hmi.cli.openapi_verb import DEFAULT_OUTPUT, openapi_document, render
from cobot_hmi.codec import command_to_json, dumps, frame_to_json, zero_command, zero_frame
from cobot_hmi.layout import O2T_ASSEMBLY, T2O_ASSEMBLY
from cobot_hmi.service.api import models

_TYPED = ("type", "$ref", "anyOf", "oneOf", "allOf", "const", "enum")


@functools.cache
def _document() -> dict[str, Any]:
    return openapi_document()


def _empty_schemas(schema: object, where: str) -> list[str]:
    """Every place under ``schema`` that says nothing about its type."""
    if not isinstance(schema, dict) or not any(key in schema for key in _TYPED):
        return [f"{where}: {str(schema)[:80]}"]
    found = []
    for key in ("anyOf", "oneOf", "allOf"):
        for i, member in enumerate(schema.get(key, [])):
            found += _empty_schemas(member, f"{where}.{key}[{i}]")
    for name, member in schema.get("properties", {}).items():
        found += _empty_schemas(member, f"{where}.{name}")
    for pattern, member in schema.get("patternProperties", {}).items():
        found += _empty_schemas(member, f"{where}[{pattern}]")
    if isinstance(schema.get("additionalProperties"), dict):
        found += _empty_schemas(schema["additionalProperties"], f"{where}.*")
    if "items" in schema:
        found += _empty_schemas(schema["items"], f"{where}[]")
    return found


def _operations() -> list[tuple[str, str, dict[str, Any]]]:
    return [
        (method.upper(), path, operation)
        for path, operations in _document()["paths"].items()
        for method, operation in operations.items()
    ]


def test_no_empty_schema_anywhere() -> None:
    document = _document()
    empty: list[str] = []
    for name, schema in document["components"]["schemas"].items():
        empty += _empty_schemas(schema, f"components.{name}")
    for method, path, operation in _operations():
        where = f"{method} {path}"
        assert operation["responses"], where
        for parameter in operation.get("parameters", []):
            empty += _empty_schemas(parameter.get("schema"), f"{where} ?{parameter['name']}")
        for media, content in operation.get("requestBody", {}).get("content", {}).items():
            empty += _empty_schemas(content.get("schema"), f"{where} body {media}")
        for status, answer in operation["responses"].items():
            contents = answer.get("content")
            if not contents:
                empty.append(f"{where} {status}: no content")
                continue
            for media, content in contents.items():
                empty += _empty_schemas(content.get("schema"), f"{where} {status} {media}")
    assert not empty, "\n".join(empty)
    # FastAPI's own 422 shape is gone: every error answer is the one envelope.
    assert "HTTPValidationError" not in document["components"]["schemas"]


def _statuses(method: str, path: str) -> set[int]:
    return {int(s) for s in _document()["paths"][path][method.lower()]["responses"]}


def test_every_route_lists_its_statuses_with_the_error_schema() -> None:
    # 400: a foreign Host header (allowed hosts), on every route.
    # 503: the audit trail cannot be written (a full disk), nothing applied.
    write = {200, 400, 401, 403, 404, 409, 413, 415, 422, 429, 503, 504}
    assert _statuses("PATCH", "/api/v1/robots/{name}/command") == write
    assert _statuses("POST", "/api/v1/robots/{name}/control/take") >= {401, 403, 404, 409, 429, 503}
    assert _statuses("GET", "/api/v1/robots/{name}/frame") == {200, 400, 401, 404}
    assert _statuses("GET", "/api/v1/audit") == {200, 400, 401, 403, 404, 422}
    assert _statuses("GET", "/healthz") == {200, 400, 503}
    envelope = "#/components/schemas/ApiErrorResponse"
    for method, path, operation in _operations():
        for status, answer in operation["responses"].items():
            if int(status) >= 400 and path not in ("/healthz", "/readyz") and "readyz" not in path:
                schema = answer["content"]["application/json"]["schema"]
                assert schema == {"$ref": envelope}, f"{method} {path} {status}"


def test_auth_answers_are_models_a_client_can_use() -> None:
    """Login, logout and who-am-I answer named models (the frontend's ``User`` is generated
    from them), and login lists its refusals (wrong password, throttled)."""

    def answer_ref(method: str, path: str) -> str:
        operation = _document()["paths"][path][method]
        schema = operation["responses"]["200"]["content"]["application/json"]["schema"]
        return str(schema["$ref"]).rsplit("/", 1)[-1]

    assert answer_ref("post", "/api/v1/auth/login") == "LoginAnswer"
    assert answer_ref("post", "/api/v1/auth/logout") == "Me"
    assert answer_ref("get", "/api/v1/auth/me") == "Me"
    schemas = _document()["components"]["schemas"]
    assert schemas["User"]["properties"]["role"]["enum"] == ["viewer", "operator", "admin"]
    assert {401, 422, 429} <= _statuses("POST", "/api/v1/auth/login")


def test_per_robot_paths_and_deprecated_single_robot_paths() -> None:
    paths = _document()["paths"]
    for suffix, method in (
        ("frame", "get"),
        ("status", "get"),
        ("command", "get"),
        ("command", "patch"),
        ("control/take", "post"),
        ("control/release", "post"),
    ):
        per_robot = paths[f"/api/v1/robots/{{name}}/{suffix}"][method]
        assert not per_robot.get("deprecated", False)
        name = next(p for p in per_robot["parameters"] if p["name"] == "name")
        assert name["in"] == "path" and name["schema"]["pattern"] == models.ROBOT_NAME_PATTERN
        old = paths[f"/api/v1/{suffix}"][method]
        assert old["deprecated"] is True, suffix
        # The same answer, documented once.
        assert old["responses"]["200"] == per_robot["responses"]["200"]
    robots = paths["/api/v1/robots"]["get"]["responses"]["200"]["content"]["application/json"]
    assert robots["schema"] == {"$ref": "#/components/schemas/RobotList"}
    for log in ("/api/v1/audit", "/api/v1/events"):
        names = {p["name"] for p in paths[log]["get"]["parameters"]}
        assert {"robot", "limit", "offset", "format"} <= names


def test_csv_and_prometheus_content_types() -> None:
    paths = _document()["paths"]
    for log in ("/api/v1/audit", "/api/v1/events"):
        content = paths[log]["get"]["responses"]["200"]["content"]
        assert set(content) == {"application/json", "text/csv"}
    metrics = paths["/metrics"]["get"]["responses"]["200"]["content"]
    assert list(metrics) == ["text/plain; version=0.0.4; charset=utf-8"]


def test_write_body_keys_are_patterns_a_fuzzer_can_use() -> None:
    patch = _document()["components"]["schemas"]["CommandPatch"]
    assert patch["additionalProperties"] is False
    assert set(patch["properties"]) == {f.name for f in O2T_ASSEMBLY.fields}
    for f in O2T_ASSEMBLY.fields:
        schema = patch["properties"][f.name]
        assert schema["additionalProperties"] is False
        (pattern,) = schema["patternProperties"]
        keys = {str(i) for i in range(f.count)}
        assert all(re.fullmatch(pattern, key) for key in keys)
        # Only the canonical ASCII indexes: no leading zero, no other script, none too large.
        for wrong in ("00", "01", str(f.count), "-1", "٣", "１", "²", " 1", "1 "):
            assert not re.fullmatch(pattern, wrong), (f.name, wrong)
    body = _document()["paths"]["/api/v1/robots/{name}/command"]["patch"]["requestBody"]
    assert body["content"]["application/json"]["schema"] == {
        "$ref": "#/components/schemas/CommandPatch"
    }


def test_websocket_messages_and_events_are_components() -> None:
    schemas = _document()["components"]["schemas"]
    stream = schemas["StreamMessage"]
    assert stream["discriminator"]["propertyName"] == "type"
    assert set(stream["discriminator"]["mapping"]) == {
        "hello",
        "frames",
        "dropped",
        "status",
        "event",
        "subscribed",  # the answer to a client's subscribe message (docs/api.md)
    }
    for name in (
        "HelloMessage",
        "FramesMessage",
        "FrameItem",
        "Frame",
        "EventMessage",
        "SubscribedMessage",
    ):
        assert name in schemas
    event = schemas["EventMessage"]["properties"]["event"]
    assert event["discriminator"]["propertyName"] == "kind"
    assert set(event["discriminator"]["mapping"]) == {
        "connection",
        "robot_state",
        "flag",
        "write",
        "control",
        "recording",
        "alarm",
        "session",
        "cycle",
        "health",  # robot health's verdicts (service.health)
    }


def test_frame_and_command_models_come_from_the_layout() -> None:
    frame = models.Frame.model_json_schema()
    for f in T2O_ASSEMBLY.fields:
        schema = frame["properties"][f.name]
        if not f.scalar and not f.element_names:
            assert schema["minItems"] == schema["maxItems"] == f.count, f.name
        if f.channels:
            assert f.channels[0] in schema["description"], f.name
    assert "robot_state_name" in frame["properties"]
    image = models.CommandImage.model_json_schema()
    assert set(image["properties"]) == {f.name for f in O2T_ASSEMBLY.fields}
    # Real JSON forms validate; a frame missing a field, or one with a wrong count, does not.
    real = orjson.loads(dumps(frame_to_json(zero_frame())))
    models.Frame.model_validate(real)
    models.CommandImage.model_validate(orjson.loads(dumps(command_to_json(zero_command()))))
    with pytest.raises(ValidationError):
        models.Frame.model_validate({**real, "controlbox_do": [True] * 15})
    with pytest.raises(ValidationError):
        models.Frame.model_validate({k: v for k, v in real.items() if k != "tool_di"})
    models.CommandPatch.model_validate(models.COMMAND_PATCH_EXAMPLE)


def test_committed_openapi_document_is_fresh(capsys: pytest.CaptureFixture[str]) -> None:
    assert DEFAULT_OUTPUT.is_file(), f"run: cobot-hmi openapi --output {DEFAULT_OUTPUT}"
    assert DEFAULT_OUTPUT.read_text(encoding="utf-8") == render(), (
        f"stale: run cobot-hmi openapi --output {DEFAULT_OUTPUT}"
    )
    assert cli_main(["openapi", "--check"]) == 0
    assert "up to date" in capsys.readouterr().out


def test_openapi_check_fails_on_a_stale_file(
    tmp_path: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    stale = tmp_path / "openapi.json"
    stale.write_text("{}\n")
    assert cli_main(["openapi", "--check", "--output", str(stale)]) == 1
    assert "stale" in capsys.readouterr().err
    assert cli_main(["openapi", "--output", str(stale)]) == 0
    assert cli_main(["openapi", "--check", "--output", str(stale)]) == 0
