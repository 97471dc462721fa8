"""Layer: emulator (HTTP I/O, asyncio). Imports the codec, the emulator's fault hooks and its
simulated robot; never the scanner or the service.

The emulator's control API (issue 4, documented in ``docs/emulator.md``): HTTP on the emulator's
address (default port 8081), served by uvicorn inside the same asyncio loop as the EtherNet/IP
target, so a handler and the target's producers never run at the same time and the robot needs
no lock. Every handler is ``async`` for that reason (FastAPI would run a plain ``def`` in a
thread).

Tests and demos use it to drive scenarios (stops, buttons, states, program, joints, inputs) and
to make the connection misbehave on purpose (drop, delay, silence, corrupt, refuse, drop TCP).
A request is validated whole before anything changes: 400 for a body that is not a JSON object,
422 for a bad field or value, 409 for a command the robot refuses in its current state; the
error body is ``{"detail": {"reason": …, "field": …}}`` like the product's API.

Guarded against the web pages a tester opens: it listens on the emulator's own address only
(``ControlApiServer`` binds the host it is given, the CLI gives ``--host``); every request but a
GET must say ``Content-Type: application/json`` (415 otherwise), which a cross-site form or a
"no-cors" fetch cannot send without a CORS preflight that this API never grants, so no page can
inject a fault or press e-stop from the tester's browser; a request must name the API by an IP
address, ``localhost``, this machine's name or an allowed name in its ``Host`` header (400
otherwise), so a page whose name was re-pointed at the emulator (DNS rebinding) is not served
either; and with a token set every request must carry ``Authorization: Bearer <token>`` (401
without one, 403 with a wrong one).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import hmac
import ipaddress
import logging
import math
import socket
import time
from collections.abc import Awaitable, Callable, Generator, Mapping, Sequence
from typing import Final, Protocol

import orjson
import uvicorn
from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse, Response

from cobot_hmi.codec import command_to_json, dumps, frame_to_json
from cobot_hmi.emulator.faults import TargetFaults
from cobot_hmi.emulator.robot import (
    RobotCommandError,
    RobotStateConflictError,
    SimulatedRobot,
)
from cobot_hmi.emulator.robot.wear import MAX_TIME_FACTOR, WearError, parse_entry

log = logging.getLogger(__name__)

DEFAULT_CONTROL_PORT: Final = 8081

MAX_DELAY_MS: Final = 10_000.0
"""Longest T→O delay the API accepts (longer is a silence: use ``t2o_silent``)."""
MAX_INTERVAL_FACTOR: Final = 100.0
"""Slowest T→O the interval fault makes, in granted RPIs (slower is a silence: the
originator's watchdog spans at most 512 RPIs, and its default 16)."""
MAX_CORRUPT_COUNT: Final = 1_000_000
MAX_EXTENDED_STATUS: Final = 0xFFFF


class StatusSource(Protocol):
    """Something more the status shows (``emulator.discovery.DiscoveryServer``)."""

    def status(self) -> dict[str, object]: ...


class EmulatorTarget(Protocol):
    """What the control API needs of the EtherNet/IP target (``emulator.target.Target``)."""

    faults: TargetFaults

    def connections(self) -> Sequence[object]: ...

    async def drop_sessions(self) -> None: ...

    def process_image_changed(self) -> None: ...

    def pump_counters(self) -> dict[str, int]: ...

    def forward_open_refusals(self) -> Sequence[object]: ...


class ControlError(Exception):
    """A refused request: HTTP ``status``, a ``reason`` and, for a bad value, the ``field``."""

    def __init__(self, status: int, reason: str, field: str | None = None) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason
        self.field = field


def _json_response(data: object, status: int = 200) -> Response:
    return Response(dumps(data), status_code=status, media_type="application/json")


def _snapshot(item: object) -> object:
    """A JSON-able view of a dataclass snapshot (plain fields only)."""
    if dataclasses.is_dataclass(item) and not isinstance(item, type):
        return {
            f.name: getattr(item, f.name)
            for f in dataclasses.fields(item)
            if isinstance(getattr(item, f.name), str | int | float | bool | type(None))
        }
    return repr(item)


async def _body(request: Request, *, required: bool = True) -> dict[str, object]:
    raw = await request.body()
    if not raw.strip():
        if required:
            raise ControlError(400, "expected a JSON object in the request body")
        return {}
    try:
        data = orjson.loads(raw)
    except orjson.JSONDecodeError as error:
        raise ControlError(400, f"the body is not JSON: {error}") from None
    if not isinstance(data, dict):
        raise ControlError(400, f"expected a JSON object, got {type(data).__name__}")
    return data


def _only(data: Mapping[str, object], allowed: Sequence[str], *, all_required: bool) -> None:
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise ControlError(
            422, f"unknown field {unknown[0]!r}; expected {', '.join(allowed)}", unknown[0]
        )
    missing = [name for name in allowed if name not in data]
    if all_required and missing:
        raise ControlError(422, f"missing field {missing[0]!r}", missing[0])
    if not data:
        raise ControlError(422, f"expected at least one of {', '.join(allowed)}")


def _bool(data: Mapping[str, object], name: str) -> bool:
    value = data[name]
    if not isinstance(value, bool):
        raise ControlError(422, f"{name}: expected true or false, got {value!r}", name)
    return value


def _int(data: Mapping[str, object], name: str, low: int, high: int) -> int:
    value = data[name]
    if isinstance(value, str) and value.lower().startswith("0x"):
        try:
            value = int(value, 16)
        except ValueError:
            raise ControlError(422, f"{name}: {data[name]!r} is not a hex number", name) from None
    if isinstance(value, bool) or not isinstance(value, int):
        raise ControlError(422, f"{name}: expected an integer, got {value!r}", name)
    if not low <= value <= high:
        raise ControlError(422, f"{name}: {value} is outside {low}–{high}", name)
    return value


def _number(data: Mapping[str, object], name: str, low: float, high: float) -> float:
    value = data[name]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ControlError(422, f"{name}: expected a finite number, got {value!r}", name)
    if not low <= value <= high:
        raise ControlError(422, f"{name}: {value} is outside {low:g}–{high:g}", name)
    return float(value)


_SAFE_METHODS: Final = frozenset({"GET", "HEAD"})


def _refusal(status: int, reason: str, headers: dict[str, str] | None = None) -> Response:
    return JSONResponse({"detail": {"reason": reason}}, status_code=status, headers=headers)


def _host_name(host_header: str) -> str:
    """The name in a ``Host`` header: without the port, brackets or a trailing dot."""
    host = host_header.strip().lower()
    if host.startswith("["):
        return host[1:].partition("]")[0]
    return host.rpartition(":")[0].rstrip(".") if ":" in host else host.rstrip(".")


def default_allowed_host_names() -> frozenset[str]:
    """``localhost`` and this machine's names (IP literals are always allowed)."""
    names = {"localhost"}
    hostname = socket.gethostname().lower()
    if hostname:
        names |= {hostname, f"{hostname}.local"}
    return frozenset(names)


def host_allowed(host_header: str, allowed_names: frozenset[str]) -> bool:
    name = _host_name(host_header)
    if name in allowed_names:
        return True
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def guard_request(
    request: Request, token: str | None, allowed_names: frozenset[str] | None = None
) -> Response | None:
    """The refusal for a request naming a foreign host, without the token or, unless a GET,
    not JSON; else ``None``."""
    names = default_allowed_host_names() if allowed_names is None else allowed_names
    host = request.headers.get("host", "")
    if not host_allowed(host, names):
        return _refusal(400, f"host {host!r} is not served here (--control-allowed-host)")
    if token is not None:
        given = request.headers.get("authorization", "")
        scheme, _, credentials = given.partition(" ")
        if scheme.lower() != "bearer" or not credentials.strip():
            return _refusal(
                401,
                "this control API needs 'Authorization: Bearer <token>'",
                {"WWW-Authenticate": "Bearer"},
            )
        if not hmac.compare_digest(credentials.strip().encode(), token.encode()):
            return _refusal(403, "wrong control API token")
    if request.method not in _SAFE_METHODS:
        media_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if media_type != "application/json":
            return _refusal(
                415,
                f"the control API takes JSON only (Content-Type: application/json), "
                f"got {media_type or 'no Content-Type'}",
            )
    return None


def _wear_command(robot: SimulatedRobot) -> Callable[[dict[str, object], float], None]:
    """``POST /wear``'s change of the robot's wear (docs/emulator.md, "Wear")."""

    def set_wear(data: dict[str, object], now_s: float) -> None:
        """``{"joint": 3, "friction_percent": 25, ...}`` and/or ``{"time_factor": 1000}``;
        ``{"joint": 2, "collision_nm": 60}``: a collision (docs/emulator.md, "Wear")."""
        joints = len(robot.model.joints)
        entry = {k: v for k, v in data.items() if k not in ("time_factor", "collision_nm")}
        factor = (
            _number(data, "time_factor", 1.0, MAX_TIME_FACTOR) if "time_factor" in data else None
        )
        collision = _number(data, "collision_nm", 1.0, 1000.0) if "collision_nm" in data else None
        try:
            parsed = parse_entry(entry, joints) if entry else None
        except WearError as error:
            raise ControlError(422, str(error), error.field) from None
        if collision is not None and set(entry) != {"joint"}:
            raise ControlError(
                422, "collision_nm: expected the joint it hits and nothing else", "collision_nm"
            )
        if parsed is None and factor is None:
            raise ControlError(422, "expected a joint's wear, a collision or a time_factor")
        if parsed is not None and collision is not None:
            robot.protective_stop(now_s)  # first: a robot that refuses it (409) changes nothing
            robot.wear.collide(parsed[0], collision, now_s)
        elif parsed is not None:
            robot.wear.set(parsed[0], parsed[1], now_s)
        if factor is not None:
            robot.wear.set_time_factor(factor, now_s)

    return set_wear


def create_control_app(
    robot: SimulatedRobot,
    target: EmulatorTarget,
    clock: Callable[[], float] = time.time,
    *,
    token: str | None = None,
    allowed_hosts: Sequence[str] = (),
    discovery: StatusSource | None = None,
) -> FastAPI:
    """The control API over ``robot`` and ``target``; ``clock`` is the target's clock;
    ``token``: required as ``Authorization: Bearer <token>`` on every request when given;
    ``allowed_hosts``: names a ``Host`` header may give besides IP addresses, ``localhost`` and
    this machine's names; ``discovery``: the discovery server, shown in the status."""
    if token is not None and not token.strip():
        raise ValueError("the control API token is empty")
    allowed_names = default_allowed_host_names() | {
        name.strip().lower().rstrip(".") for name in allowed_hosts if name.strip()
    }
    app = FastAPI(
        title="cobot-hmi emulator control API",
        description="Scenarios and faults for the emulated robot (docs/emulator.md).",
    )
    _install_guard_and_errors(app, token, allowed_names)
    _add_status(app, robot, target, clock, discovery)
    _RobotCommands(app, robot, target, clock).add_all()
    _add_faults(app, target)
    return app


def _install_guard_and_errors(
    app: FastAPI, token: str | None, allowed_names: frozenset[str]
) -> None:
    """Every request's token and Host checked first; refusals answered as JSON."""

    @app.middleware("http")
    async def _guard(
        request: Request, call_next: Callable[[Request], Awaitable[Response]]
    ) -> Response:
        refusal = guard_request(request, token, allowed_names)
        if refusal is not None:
            return refusal
        return await call_next(request)

    @app.exception_handler(ControlError)
    async def _control_error(_: Request, error: ControlError) -> JSONResponse:
        detail: dict[str, object] = {"reason": error.reason}
        if error.field is not None:
            detail["field"] = error.field
        return JSONResponse({"detail": detail}, status_code=error.status)

    @app.exception_handler(RobotCommandError)
    async def _robot_error(_: Request, error: RobotCommandError) -> JSONResponse:
        status = 409 if isinstance(error, RobotStateConflictError) else 422
        return JSONResponse({"detail": {"reason": str(error)}}, status_code=status)


def _add_status(
    app: FastAPI,
    robot: SimulatedRobot,
    target: EmulatorTarget,
    clock: Callable[[], float],
    discovery: StatusSource | None,
) -> None:
    @app.get("/status")
    async def status() -> Response:
        now_s = clock()
        counters = getattr(target, "counters", None)
        return _json_response(
            {
                "time": now_s,
                "frame": frame_to_json(robot.produce_frame(now_s)),
                "robot": robot.status(),
                "wear": robot.wear.view(now_s),
                "connections": [_snapshot(c) for c in target.connections()],
                "faults": dataclasses.asdict(target.faults),
                "plc_command": command_to_json(robot.command_image()),
                "target_counters": _snapshot(counters) if counters is not None else None,
                "pump": target.pump_counters(),
                "forward_open_refusals": [_snapshot(r) for r in target.forward_open_refusals()],
                "discovery": discovery.status() if discovery is not None else None,
            }
        )


_Apply = Callable[[dict[str, object], float], None]
"""A command's action on its request body at the target's time."""


def _no_body(action: Callable[[float], None]) -> _Apply:
    def apply(data: dict[str, object], now_s: float) -> None:
        if data:
            raise ControlError(422, f"no fields expected, got {', '.join(sorted(data))}")
        action(now_s)

    return apply


def _flag(name: str, action: Callable[[bool, float], None]) -> _Apply:
    def apply(data: dict[str, object], now_s: float) -> None:
        _only(data, (name,), all_required=True)
        action(_bool(data, name), now_s)

    return apply


class _RobotCommands:
    """The robot's commands (``POST /estop``, ``/state``, ``/wear`` …): each applied at the
    target's time, in the very next T→O packet, answered with the robot's view."""

    def __init__(
        self,
        app: FastAPI,
        robot: SimulatedRobot,
        target: EmulatorTarget,
        clock: Callable[[], float],
    ) -> None:
        self.app, self.robot, self.target, self.clock = app, robot, target, clock

    def add_all(self) -> None:
        robot = self.robot
        self.route("/estop", _no_body(robot.estop), needs_body=False)
        self.route("/reset", _no_body(robot.reset), needs_body=False)
        self.route("/protective-stop", _no_body(robot.protective_stop), needs_body=False)
        self.route("/teach-button", _flag("pressed", robot.set_teach_button), needs_body=True)
        self.route("/power-button", _flag("pressed", robot.set_power_button), needs_body=True)
        self.route("/program", _flag("running", robot.set_program_running), needs_body=True)
        self.route("/collaborative", _flag("enabled", robot.set_collaborative), needs_body=True)
        self.route("/state", self.set_state, needs_body=True)
        self.route("/joints", self.set_joints, needs_body=True)
        self.route("/inputs", self.set_inputs, needs_body=True)
        self.route("/tool-offset", self.set_tool_offset, needs_body=True)
        self.route("/wear", _wear_command(robot), needs_body=True)
        self.route("/wear/clear", _no_body(robot.wear.clear), needs_body=False)

    def route(self, path: str, apply: _Apply, *, needs_body: bool) -> None:
        async def handler(request: Request) -> Response:
            data = await _body(request, required=needs_body)
            apply(data, self.clock())
            self.target.process_image_changed()  # in the very next T→O packet
            return _json_response({"robot": self.robot_view()})

        handler.__name__ = "post_" + path.strip("/").replace("-", "_")
        self.app.post(path)(handler)

    def robot_view(self) -> dict[str, object]:
        now_s = self.clock()
        frame = self.robot.produce_frame(now_s)
        return {
            "robot_state": frame.robot_state,
            "robot_state_name": frame_to_json(frame)["robot_state_name"],
            **self.robot.status(),
            "wear": self.robot.wear.view(now_s),
        }

    def set_state(self, data: dict[str, object], now_s: float) -> None:
        _only(data, ("robot_state",), all_required=True)
        self.robot.force_state(_int(data, "robot_state", 0, 255), now_s)

    def set_joints(self, data: dict[str, object], now_s: float) -> None:
        _only(data, ("joint_position",), all_required=True)
        values = data["joint_position"]
        if not isinstance(values, list):
            raise ControlError(
                422, "joint_position: expected an array of 6 numbers", "joint_position"
            )
        self.robot.hold_joints(values, now_s)

    def set_inputs(self, data: dict[str, object], now_s: float) -> None:
        if not data:
            raise ControlError(422, "expected at least one input map")
        self.robot.set_inputs(data, now_s)  # type: ignore[arg-type]  # checked by RobotIO

    def set_tool_offset(self, data: dict[str, object], now_s: float) -> None:
        _only(data, ("position", "orientation"), all_required=True)
        position, orientation = data["position"], data["orientation"]
        if not isinstance(position, list) or not isinstance(orientation, list):
            raise ControlError(422, "position and orientation: expected arrays of 3 numbers")
        self.robot.set_tool_offset(position, orientation, now_s)


_FAULT_FIELDS: Final = (
    "t2o_drop_percent",
    "t2o_delay_ms",
    "t2o_interval_factor",
    "t2o_silent",
    "t2o_corrupt_count",
    "refuse_next_forward_open",
    "drop_sessions",
)


def _fault_changes(data: dict[str, object]) -> dict[str, object]:
    """The faults a body sets, each checked (``ControlError`` naming the first bad one)."""
    _only(data, _FAULT_FIELDS, all_required=False)
    changes: dict[str, object] = {}
    if "t2o_drop_percent" in data:
        changes["t2o_drop_percent"] = _number(data, "t2o_drop_percent", 0.0, 100.0)
    if "t2o_delay_ms" in data:
        changes["t2o_delay_ms"] = _number(data, "t2o_delay_ms", 0.0, MAX_DELAY_MS)
    if "t2o_interval_factor" in data:
        changes["t2o_interval_factor"] = _number(
            data, "t2o_interval_factor", 1.0, MAX_INTERVAL_FACTOR
        )
    if "t2o_silent" in data:
        changes["t2o_silent"] = _bool(data, "t2o_silent")
    if "t2o_corrupt_count" in data:
        changes["t2o_corrupt_count"] = _int(data, "t2o_corrupt_count", 0, MAX_CORRUPT_COUNT)
    if "refuse_next_forward_open" in data:
        changes["refuse_next_forward_open"] = (
            None
            if data["refuse_next_forward_open"] is None
            else _int(data, "refuse_next_forward_open", 1, MAX_EXTENDED_STATUS)
        )
    return changes


def _add_faults(app: FastAPI, target: EmulatorTarget) -> None:
    @app.post("/faults")
    async def set_faults(request: Request) -> Response:
        data = await _body(request)
        changes = _fault_changes(data)
        drop = _bool(data, "drop_sessions") if "drop_sessions" in data else False
        for name, value in changes.items():  # everything valid: now apply
            setattr(target.faults, name, value)
        # At once, not at the class 1 engine's next wake-up (which, while T→O streams, waits
        # for the robot's next change of its own: up to its monitoring period).
        target.process_image_changed()
        if drop:
            await target.drop_sessions()
        return _json_response(
            {"faults": dataclasses.asdict(target.faults), "sessions_dropped": drop}
        )

    @app.post("/faults/clear")
    async def clear_faults() -> Response:
        target.faults.reset()
        target.process_image_changed()
        return _json_response({"faults": dataclasses.asdict(target.faults)})


class _EmbeddedServer(uvicorn.Server):
    """uvicorn without its signal handlers (the emulator's process owns its signals) and
    without its ten wake-ups a second (``main_loop``)."""

    def __init__(self, config: uvicorn.Config) -> None:
        super().__init__(config)
        self.exit_asked = asyncio.Event()
        """Set with ``should_exit`` by ``ControlApiServer.stop``: the main loop ends at once."""

    @contextlib.contextmanager
    def capture_signals(self) -> Generator[None, None, None]:
        yield

    async def main_loop(self) -> None:
        """uvicorn's looks at ``should_exit`` every 100 ms, a tenth of the emulator's idle
        wake-ups; this one once a second, to refresh the Date header as uvicorn does (its
        ``on_tick`` does that at every tenth tick), and at once when ``stop`` asks."""
        counter = 0
        while not await self.on_tick(counter):
            counter = (counter + 10) % 864000
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.exit_asked.wait(), 1.0)


class ControlApiServer:
    """The control API served by uvicorn in the running asyncio loop.

    ``await start()`` binds (an ``OSError`` if the address is taken) and returns once the server
    accepts; ``await stop()`` shuts it down and waits for it.
    """

    def __init__(self, app: FastAPI, host: str, port: int = DEFAULT_CONTROL_PORT) -> None:
        self.app = app
        self.host = host
        self.port = port
        self._server: _EmbeddedServer | None = None
        self._task: asyncio.Task[None] | None = None

    async def start(self) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            # Accepted sockets inherit it: without it a keep-alive request waits ~40 ms for the
            # client's delayed ACK between the response's header and body writes (measured).
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.bind((self.host, self.port))
            sock.listen(128)
            sock.setblocking(False)
        except OSError:
            sock.close()
            raise
        self.port = sock.getsockname()[1]
        config = uvicorn.Config(
            self.app, log_level="warning", lifespan="off", access_log=False, loop="none"
        )
        server = _EmbeddedServer(config)
        self._server = server
        self._task = asyncio.create_task(server.serve(sockets=[sock]), name="control-api")
        for _ in range(500):  # up to 5 s: the server starts in a few loop turns
            if server.started or self._task.done():
                break
            await asyncio.sleep(0.01)
        if self._task.done():
            await self._task  # raises why it stopped
        log.info("emulator control API on http://%s:%d", self.host, self.port)

    async def stop(self) -> None:
        if self._server is None or self._task is None:
            return
        self._server.should_exit = True
        self._server.exit_asked.set()
        with contextlib.suppress(asyncio.CancelledError):
            await self._task
        self._server = None
        self._task = None
