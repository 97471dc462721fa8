"""Layer: service. The one write pipeline: every writer of a robot's outputs goes through it.

``submit_write`` takes a writer (who) and a body (what, raw JSON bytes or already parsed) for one
robot and runs the same steps for every door (HTTP today; MQTT or a script later):

1. authorize: a writer without a login is 401, one below the operator role 403;
2. parse and validate the whole body against the image being sent (422 naming the field;
   nothing is applied);
3. whether anyone may write now (connection, input-only mode) and whether this writer holds
   control (409);
4. audit: a ``pending`` row committed before the robot is commanded;
5. apply: the new O→T image;
6. confirm: the robot's own frame shows the outputs (bit input registers: the packet carrying
   them went out), or 504 with what the robot reports;
7. answer: the row's outcome committed, a ``write`` event, the ``WriteOutcome``.

Every refusal is audited with its outcome (``unauthorized``, ``forbidden``, ``invalid``,
``refused``, ``timeout``) and counted; a crash at any point leaves the attempt on disk (a
``pending`` row is marked ``interrupted`` at the next start). A full disk: a write whose
``pending`` row cannot be written is refused, 503 "the audit trail cannot be written: disk
full …", before anything is applied; an outcome that cannot be written after the robot acted
waits in memory and is written when there is room (``store``, ``audit_backlog``), the answer
saying so (``audit_pending``). Taking and releasing control go through the same authorization
and audit (``take_control``, ``release_control``). Imports the service's parts, never a route.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final, Protocol

import orjson

from cobot_hmi.codec import CommandImage, Frame, command_to_json
from cobot_hmi.scanner.originator import NotConnectedError, ReadOnlyError
from cobot_hmi.service.access.auth import Session
from cobot_hmi.service.access.users import Role
from cobot_hmi.service.errors import ApiError, AuditUnavailableError
from cobot_hmi.service.labels import labels_of, write_summary
from cobot_hmi.service.robots.frame_notifier import FrameRecord
from cobot_hmi.service.robots.robot import WriteCounters
from cobot_hmi.service.storage.store import AuditEntry, Store
from cobot_hmi.service.writes.validation import (
    PlannedWrite,
    WriteValidationError,
    frame_shows,
    plan_write,
    robot_reports,
)

ACTION: Final = "write"
MAX_BODY_BYTES: Final = 64 * 1024
"""A whole O→T image as index maps is ~3 KiB; anything much larger is not a write."""

_STATUS_OUTCOME: Final = {401: "unauthorized", 403: "forbidden", 422: "invalid"}
AUDIT_PENDING_WARNING: Final = (
    "the audit trail cannot be written now (disk full): this write's audit row waits in memory "
    "and is written as soon as there is room"
)


# --------------------------------------------------------------------------- what it needs


class _Link(Protocol):
    @property
    def command(self) -> CommandImage: ...

    async def set_command(self, image: CommandImage) -> int: ...

    async def wait_sent(self, packets_out: int, timeout_s: float) -> bool: ...


class _Frames(Protocol):
    """The robot's frames (``robots.frame_notifier.FrameNotifier``)."""

    @property
    def seq(self) -> int: ...

    @property
    def latest(self) -> FrameRecord | None: ...


class _Confirmation(Protocol):
    """Writes waiting for a frame (``robots.confirmation.FrameWaiters``)."""

    async def wait_for_frame(
        self, predicate: _FramePredicate, after_seq: int, timeout_s: float
    ) -> FrameRecord | None: ...


class _FramePredicate(Protocol):
    def __call__(self, frame: Frame, /) -> bool: ...


class _Holder(Protocol):
    @property
    def user(self) -> str: ...


class _Control(Protocol):
    @property
    def lock(self) -> asyncio.Lock: ...

    @property
    def holder(self) -> _Holder | None: ...

    def refusal_to_write(self) -> str | None: ...

    def holds(self, session: Session) -> bool: ...

    async def take(self, session: Session, client: str | None) -> dict[str, object]: ...

    async def release(self, session: Session, client: str | None) -> dict[str, object]: ...


class _Tags(Protocol):
    @property
    def names(self) -> Mapping[str, str]: ...


class WriteTarget(Protocol):
    """What the pipeline uses of a robot (``service.robots.robot.RobotRuntime`` is one)."""

    @property
    def name(self) -> str: ...

    @property
    def link(self) -> _Link: ...

    @property
    def frames(self) -> _Frames: ...

    @property
    def confirmation(self) -> _Confirmation: ...

    def publish_event(self, event: dict[str, object]) -> None: ...

    @property
    def control(self) -> _Control: ...

    @property
    def writes(self) -> WriteCounters: ...

    @property
    def store(self) -> Store: ...

    @property
    def tags(self) -> _Tags: ...


# --------------------------------------------------------------------------- who and what came


@dataclass(frozen=True, slots=True)
class Writer:
    """Who writes: a logged-in user (with the session that may hold control), or a client of
    another door (an MQTT client id) acting with a role."""

    user: str | None
    role: Role | None
    client: str | None
    """The writer's address or client id, as the audit shows it."""
    session: Session | None = None

    @classmethod
    def from_session(cls, session: Session | None, client: str | None) -> Writer:
        if session is None:
            return cls(None, None, client)
        return cls(session.user.name, session.user.role, client, session)


@dataclass(frozen=True, slots=True)
class WriteOutcome:
    """What became of a write: ``status`` 200 (confirmed) or the refusal's HTTP status."""

    status: int
    outcome: str
    """``confirmed``, ``unauthorized``, ``forbidden``, ``invalid``, ``refused`` or ``timeout``."""
    reason: str | None = None
    field: str | None = None
    image: dict[str, object] | None = None
    """The whole O→T image after the write (confirmed only)."""
    latency_ms: float | None = None
    seq: int | None = None
    """The stream's number of the robot's frame that showed it (confirmed by a frame only)."""
    robot_reports: dict[str, object] | None = None
    """What the robot shows of the written elements (timeout only)."""
    audit_pending: bool = False
    """The outcome could not be written to the audit trail yet (a full disk): it waits in
    memory (``store.audit_backlog``) and is written when there is room."""

    @property
    def ok(self) -> bool:
        return self.status == 200

    def answer(self) -> dict[str, object]:
        """The 200 body (``models.WriteConfirmed``)."""
        body: dict[str, object] = {
            "outcome": self.outcome,
            "image": self.image,
            "latency_ms": self.latency_ms,
            "seq": self.seq,
        }
        if self.audit_pending:
            body |= {"audit_pending": True, "warning": AUDIT_PENDING_WARNING}
        return body

    def error(self) -> ApiError:
        """The refusal as the HTTP API answers it."""
        extra: dict[str, object] = {"field": self.field}
        if self.robot_reports is not None:
            extra["robot_reports"] = self.robot_reports
        error = ApiError(self.status, self.reason or self.outcome, **extra)
        if self.status == 401:
            error.headers["WWW-Authenticate"] = "Bearer"
        return error


class _RefusedError(Exception):
    def __init__(self, status: int, reason: str, field: str | None = None) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason
        self.field = field


# --------------------------------------------------------------------------- the steps


def authorize(writer: Writer, what: str, role: Role = Role.OPERATOR) -> None:
    """Step 1: the writer's role; ``_RefusedError`` 401 / 403."""
    if writer.user is None or writer.role is None:
        raise _RefusedError(401, f"login required to {what}")
    if writer.role < role:
        raise _RefusedError(
            403, f"{what} needs the {role.label} role; {writer.user} is {writer.role.label}"
        )


def parse_body(body: object) -> object:
    """Step 2a: JSON bytes or text to a value (an already parsed body passes through)."""
    if isinstance(body, bytes | bytearray | memoryview | str):
        raw = body.encode() if isinstance(body, str) else bytes(body)
        if len(raw) > MAX_BODY_BYTES:
            raise _RefusedError(422, f"the body is larger than {MAX_BODY_BYTES} bytes")
        try:
            return orjson.loads(raw)
        except orjson.JSONDecodeError as error:
            raise _RefusedError(422, f"the body is not JSON: {error}") from None
    return body


def validate(body: object, base: CommandImage) -> PlannedWrite:
    """Step 2b: the whole body against the image being sent; 422 naming the field."""
    try:
        return plan_write(body, base)
    except WriteValidationError as error:
        raise _RefusedError(422, error.reason, error.field) from None


def _body_fields(body: object) -> list[str]:
    """``name.index`` keys a malformed body names, as far as they can be read."""
    if not isinstance(body, Mapping):
        return []
    fields: list[str] = []
    for name, value in body.items():
        if isinstance(value, Mapping):
            fields.extend(f"{name}.{key}" for key in value)
        else:
            fields.append(str(name))
    return fields


async def submit_write(
    robot: WriteTarget, writer: Writer, body: object, *, origin: str
) -> WriteOutcome:
    """Run the pipeline (module docstring) for one write to ``robot``; never raises a refusal,
    it is in the outcome. ``origin`` names the door (``PATCH /api/v1/robots/{name}/command``)."""
    started = time.perf_counter()
    parsed: object = None
    try:
        authorize(writer, "writing")
        parsed = parse_body(body)
        async with robot.control.lock:  # take, release and writes never interleave
            return await _write_locked(robot, writer, parsed, origin, started)
    except _RefusedError as refusal:
        outcome = _STATUS_OUTCOME.get(refusal.status, "refused")
        robot.writes.outcomes[outcome] += 1
        words = _refused_words(robot, parsed) if refusal.status in (409, 503) else None
        # Nothing was applied: the row is kept in memory if the disk is full (audit_backlog).
        await robot.store.keep_audit(
            AuditEntry(
                writer.user,
                writer.client,
                ACTION,
                _body_fields(parsed),
                None,
                _jsonable(parsed),
                outcome,
                refusal.reason,
                robot=robot.name,
                origin=origin,
                summary=None if words is None else words.summary,
                tags=None if words is None else words.tags or None,
            )
        )
        return WriteOutcome(refusal.status, outcome, refusal.reason, refusal.field)


def _refused_words(robot: WriteTarget, body: object) -> _Words | None:
    """A valid write refused for now (409: control, connection): what it asked, in words."""
    try:
        return _Words.of(robot, plan_write(body, robot.link.command))
    except WriteValidationError:
        return None


def _jsonable(value: object) -> object:
    """What of a body the audit can keep as JSON (all of it, unless orjson cannot say it)."""
    try:
        orjson.dumps(value)
    except TypeError:
        return repr(value)[:1000]
    return value


def _refusal_to_write(robot: WriteTarget, writer: Writer) -> str | None:
    control = robot.control
    refusal = control.refusal_to_write()
    if refusal is not None:
        return refusal
    session = writer.session
    if session is not None and control.holds(session):
        return None
    holder = control.holder
    if holder is None:
        path = f"/api/v1/robots/{robot.name}/control/take"
        return f"take control first (POST {path})"
    if session is not None and session.user.name == holder.user:
        return (
            f"control is held by you ({holder.user}) in another session (another window or "
            "device): only the session holding it may write"
        )
    return f"control is held by {holder.user}"


async def _write_locked(
    robot: WriteTarget, writer: Writer, body: object, origin: str, started: float
) -> WriteOutcome:
    link = robot.link
    before_image = link.command
    plan = validate(body, before_image)
    refusal = _refusal_to_write(robot, writer)
    if refusal is not None:
        raise _RefusedError(409, refusal)
    words = _Words.of(robot, plan)
    entry = AuditEntry(
        writer.user,
        writer.client,
        ACTION,
        plan.field_names,
        plan.values(before_image),
        plan.values(plan.image),
        "pending",
        None,
        robot=robot.name,
        origin=origin,
        summary=words.summary,
        tags=words.tags or None,
    )
    row_id = await _pending_row(robot.store, entry, "the write was not applied")
    after_seq = robot.frames.seq
    try:
        packets_out = await link.set_command(plan.image)
    except (NotConnectedError, ReadOnlyError) as error:
        audited = await _finish(
            robot, row_id, writer=writer, words=words, outcome="refused", reason=str(error)
        )
        return WriteOutcome(409, "refused", str(error), audit_pending=not audited)
    deadline = started + robot.writes.timeout_s
    confirmed, shown_seq = await _confirmation(robot, plan, after_seq, packets_out, deadline)
    latency_ms = (time.perf_counter() - started) * 1000
    if not confirmed:
        return await _timed_out(robot, row_id, writer, words, plan)
    audited = await _finish(
        robot, row_id, writer=writer, words=words, outcome="confirmed", reason=None
    )
    return WriteOutcome(
        200,
        "confirmed",
        image=command_to_json(plan.image),
        latency_ms=round(latency_ms, 3),
        seq=shown_seq,
        audit_pending=not audited,
    )


async def _confirmation(
    robot: WriteTarget, plan: PlannedWrite, after_seq: int, packets_out: int, deadline: float
) -> tuple[bool, int | None]:
    """Step 6: whether the robot's own frames showed the outputs (after frame ``after_seq``)
    and the O→T packets carried the bit input registers before ``deadline`` (perf_counter);
    the number of the frame that showed them."""
    confirmed, shown_seq = True, None
    if plan.by_frame:
        item = await robot.confirmation.wait_for_frame(
            lambda f: frame_shows(f, plan.image, plan.by_frame),
            after_seq,
            max(0.0, deadline - time.perf_counter()),
        )
        confirmed, shown_seq = item is not None, item.seq if item is not None else None
    if confirmed and plan.by_packet:
        remaining_s = max(0.0, deadline - time.perf_counter())
        confirmed = await robot.link.wait_sent(packets_out, remaining_s)
    return confirmed, shown_seq


async def _timed_out(
    robot: WriteTarget, row_id: int, writer: Writer, words: _Words, plan: PlannedWrite
) -> WriteOutcome:
    """A write the robot did not confirm in time: audited so, 504 with what it reports."""
    timeout_s = robot.writes.timeout_s
    latest = robot.frames.latest
    reports = robot_reports(latest.frame if latest is not None else None, plan.by_frame)
    if plan.by_frame:
        reason = f"the robot did not show the new outputs within {timeout_s * 1000:.0f} ms"
    else:
        reason = (
            "the O→T packet with the bit input registers did not go out within "
            f"{timeout_s * 1000:.0f} ms"
        )
    audited = await _finish(
        robot, row_id, writer=writer, words=words, outcome="timeout", reason=reason
    )
    return WriteOutcome(504, "timeout", reason, robot_reports=reports, audit_pending=not audited)


async def _pending_row(store: Store, entry: AuditEntry, not_done: str) -> int:
    """Step 4: the ``pending`` row, committed before anything is applied (without its own
    fsync: the outcome's covers it, ``store``); ``_RefusedError`` 503 when the audit trail
    cannot be written (``not_done`` says what was therefore not done)."""
    try:
        return await store.add_audit(entry, fsync=False)
    except AuditUnavailableError as error:
        raise _RefusedError(503, error.refusing(not_done).reason) from None


@dataclass(frozen=True, slots=True)
class _Words:
    """A planned write as people read it: values by key, the spec's labels, tag names, and the
    summary ("AO 1 type = voltage, AO 1 = 5 V": the unit follows the type written with it)."""

    fields: list[str]
    values: dict[str, object]
    labels: dict[str, str]
    tags: dict[str, str]
    summary: str

    @classmethod
    def of(cls, robot: WriteTarget, plan: PlannedWrite) -> _Words:
        fields = plan.field_names
        values = plan.values(plan.image)
        names = robot.tags.names
        tags = {key: names[key] for key in fields if key in names}
        summary = write_summary(values, tuple(plan.image.analog_output_type), tags)
        return cls(fields, values, labels_of(fields), tags, summary)


async def _finish(
    robot: WriteTarget,
    row_id: int,
    *,
    writer: Writer,
    words: _Words,
    outcome: str,
    reason: str | None,
) -> bool:
    """The outcome counted, committed (``False``: it waits in memory for room on the disk)
    and announced."""
    robot.writes.outcomes[outcome] += 1
    audited = await robot.store.finish_audit(row_id, outcome, reason)
    robot.publish_event(
        {
            "kind": "write",
            "time": time.time(),
            "robot": robot.name,
            "user": writer.user,
            "fields": words.fields,
            "outcome": outcome,
            "reason": reason,
            "values": words.values,
            "labels": words.labels,
            "tags": words.tags,
            "summary": words.summary,
        }
    )
    return audited


# --------------------------------------------------------------------------- other actions


async def authorize_audited(
    store: Store,
    writer: Writer,
    *,
    action: str,
    what: str,
    robot: str | None,
    origin: str,
    role: Role = Role.OPERATOR,
    fields: list[str] | None = None,
    requested: object = None,
) -> str:
    """Step 1 for an action other than a write (acknowledging or shelving an alarm, tag
    names): the writer's role, a refusal audited as a write's is (``ApiError`` 401 / 403).
    The writer's user name."""
    try:
        authorize(writer, what, role)
    except _RefusedError as refusal:
        outcome = _STATUS_OUTCOME.get(refusal.status, "refused")
        await store.keep_audit(
            AuditEntry(
                writer.user,
                writer.client,
                action,
                fields or [],
                None,
                _jsonable(requested),
                outcome,
                refusal.reason,
                robot=robot,
                origin=origin,
            )
        )
        raise WriteOutcome(refusal.status, outcome, refusal.reason).error() from None
    assert writer.user is not None
    return writer.user


# --------------------------------------------------------------------------- control


async def take_control(robot: WriteTarget, writer: Writer, *, origin: str) -> dict[str, object]:
    """Authorize (audited) and take control of ``robot`` for the writer's session; the
    ``ControlStatus``. ``ApiError`` for a refusal."""
    session = await _control_session(robot, writer, "control.take", origin)
    return _as_seen_by(await robot.control.take(session, writer.client), session)


async def release_control(robot: WriteTarget, writer: Writer, *, origin: str) -> dict[str, object]:
    """Authorize (audited) and release control of ``robot`` (an admin: anyone's)."""
    session = await _control_session(robot, writer, "control.release", origin)
    return _as_seen_by(await robot.control.release(session, writer.client), session)


def _as_seen_by(status: dict[str, object], session: Session) -> dict[str, object]:
    """A ``ControlStatus`` with ``holder.session_is_yours`` for the session that asked."""
    holder = status.get("holder")
    if isinstance(holder, dict):
        return {
            **status,
            "holder": {**holder, "session_is_yours": holder.get("session") == session.id},
        }
    return status


async def _control_session(robot: WriteTarget, writer: Writer, action: str, origin: str) -> Session:
    try:
        authorize(writer, "control")
        if writer.session is None:
            raise _RefusedError(409, "control belongs to a login session; this writer has none")
    except _RefusedError as refusal:
        outcome = _STATUS_OUTCOME.get(refusal.status, "refused")
        await robot.store.keep_audit(
            AuditEntry(
                writer.user,
                writer.client,
                action,
                [],
                None,
                None,
                outcome,
                refusal.reason,
                robot=robot.name,
                origin=origin,
            )
        )
        outcome_error = WriteOutcome(refusal.status, outcome, refusal.reason, refusal.field)
        raise outcome_error.error() from None
    return writer.session
