"""Layer: service. I/O checkouts (loop checks) of one robot: their points and results, kept in
the service's database as they change (tables ``checkouts`` and ``checkout_points``,
``service.storage.migrations`` step 5), so a checkout survives a restart and several checkers
work on one at once, each action naming who did it.

A point's ``result`` is ``untested``, ``seen``, ``pass`` or ``fail``:

- a digital input is ``seen`` when the robot's frames show it change (``mark_seen``, called by
  the frame watcher, ``commissioning.watcher``): the frame's time, its number and both values;
- an analog input is ``seen`` once the checker captured its value at two points of their choice
  (``capture``);
- an output is switched by the checker through the write pipeline (``switched``: the robot
  confirmed the value); every switch is kept in order with its confirmation time, so the
  evidence of "DO 3 on, confirmed; off, confirmed" survives the last switch off;
- the checker records ``pass`` or ``fail`` with a comment (``record``): ``pass`` only for an
  input seen or an output the robot confirmed, ``fail`` always, and only with a comment saying
  what is wrong (422 without one).

A robot has at most one open checkout: starting another while one is open is refused (409,
naming the open one, to be resumed). A closed checkout is read-only (``CheckoutError`` 409).
This module keeps the state and its rows; authorization, audit and the write itself are the
routes' (``api.routes.checkouts``).
"""

from __future__ import annotations

import asyncio
import sqlite3
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import orjson

from cobot_hmi.service.commissioning.points import (
    ANALOG_SAMPLES,
    CHECK_POINTS,
    CheckPoint,
)
from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.storage.store import Store

Result = Literal["untested", "seen", "pass", "fail"]
RESULTS: tuple[Result, ...] = ("untested", "seen", "pass", "fail")


class CheckoutError(ApiError):
    """A checkout action refused: ``status`` is the HTTP status the API answers."""

    def __init__(self, status: int, reason: str, field: str | None = None) -> None:
        super().__init__(status, reason, field=field)


@dataclass(slots=True)
class PointState:
    """One point of one checkout as it stands."""

    point: CheckPoint
    result: Result = "untested"
    seen: dict[str, Any] | None = None
    """``{"time", "seq", "before", "after"}`` of the first edge the frames showed."""
    samples: list[dict[str, Any]] = field(default_factory=list)
    """Analog inputs: ``{"time", "value", "by"}`` per capture."""
    switched: dict[str, Any] | None = None
    """Outputs: the last value the robot confirmed, ``{"time", "value", "by", "latency_ms"}``."""
    switches: list[dict[str, Any]] = field(default_factory=list)
    """Outputs: every switch the robot confirmed, oldest first, each as ``switched``
    (``time``: when the service had the robot's confirmation; ``seq``: the frame showing it)."""
    recorded: dict[str, Any] | None = None
    """``{"time", "by", "comment"}`` of the checker's pass or fail."""

    def data(self) -> dict[str, Any]:
        return {
            "seen": self.seen,
            "samples": self.samples,
            "switched": self.switched,
            "switches": self.switches,
            "recorded": self.recorded,
        }

    def answer(self, tag: str | None) -> dict[str, object]:
        """``CheckoutPoint`` of the API."""
        p, seen, switched, recorded = self.point, self.seen, self.switched, self.recorded
        return {
            "key": p.key,
            "label": p.label,
            "tag": tag,
            "kind": p.kind,
            "signal": p.signal,
            "result": self.result,
            "seen_at": seen["time"] if seen else None,
            "seen_before": seen["before"] if seen else None,
            "seen_after": seen["after"] if seen else None,
            "samples": self.samples,
            "switched_at": switched["time"] if switched else None,
            "switched_value": switched["value"] if switched else None,
            "switched_by": switched["by"] if switched else None,
            "switches": self.switches,
            "recorded_at": recorded["time"] if recorded else None,
            "recorded_by": recorded["by"] if recorded else None,
            "comment": recorded["comment"] if recorded else None,
        }


@dataclass(slots=True)
class Checkout:
    id: int
    robot: str
    started_at: float
    started_by: str
    identity: dict[str, object] | None = None
    closed_at: float | None = None
    closed_by: str | None = None
    points: dict[str, PointState] = field(default_factory=dict)

    @property
    def closed(self) -> bool:
        return self.closed_at is not None

    def counts(self) -> dict[str, int]:
        counts: dict[str, int] = dict.fromkeys(RESULTS, 0)
        for state in self.points.values():
            counts[state.result] += 1
        return counts

    def summary(self) -> dict[str, object]:
        """``CheckoutSummary`` of the API (no points)."""
        return {
            "id": self.id,
            "robot": self.robot,
            "started_at": self.started_at,
            "started_by": self.started_by,
            "closed_at": self.closed_at,
            "closed_by": self.closed_by,
            "identity": self.identity,
            "counts": self.counts(),
        }

    def answer(self, tags: Mapping[str, str]) -> dict[str, object]:
        """``Checkout`` of the API."""
        points = [s.answer(tags.get(k)) for k, s in self.points.items()]
        return {**self.summary(), "points": points}

    def point(self, key: str) -> PointState:
        state = self.points.get(key)
        if state is None:
            raise CheckoutError(
                404, f"{key!r} is not a point of the checkout (field.index, e.g. controlbox_di.4)"
            )
        return state

    def open_point(self, key: str) -> PointState:
        if self.closed:
            raise CheckoutError(409, f"checkout {self.id} is closed: it is read-only")
        return self.point(key)


class CheckoutBook:
    """Every checkout of one robot: the open ones in memory, all of them in the database."""

    def __init__(self, robot: str, store: Store) -> None:
        self.robot = robot
        self.store = store
        self.open: dict[int, Checkout] = {}
        """Open checkouts by id (the frame watcher marks their inputs)."""
        self._starting = asyncio.Lock()
        """Two starts at once: the second sees the first's checkout open."""

    async def load(self) -> None:
        """The open checkouts from the database (after a restart: they go on)."""
        self.open = {c.id: c for c in await self.store.call(self._load_open, fsync=False)}

    def _load_open(self, db: sqlite3.Connection) -> list[Checkout]:
        rows = db.execute(
            "SELECT id FROM checkouts WHERE robot = ? AND closed_at IS NULL ORDER BY id",
            (self.robot,),
        ).fetchall()
        return [c for (row_id,) in rows if (c := _read(db, row_id)) is not None]

    async def start(self, by: str, identity: dict[str, object] | None) -> Checkout:
        """A new checkout; 409 while one is open (it is resumed, not started again)."""
        async with self._starting:
            return await self._start(by, identity)

    async def _start(self, by: str, identity: dict[str, object] | None) -> Checkout:
        already = next(iter(self.open.values()), None)
        if already is not None:
            raise CheckoutError(
                409,
                f"checkout {already.id} of robot {self.robot} is open (started by "
                f"{already.started_by}): resume it, or close it before starting another",
                "checkout",
            )
        started_at = time.time()
        checkout_id = await self.store.call(
            lambda db: _insert(db, self.robot, started_at, by, identity)
        )
        checkout = Checkout(checkout_id, self.robot, started_at, by, identity)
        checkout.points = {p.key: PointState(p) for p in CHECK_POINTS}
        self.open[checkout_id] = checkout
        return checkout

    async def get(self, checkout_id: int) -> Checkout:
        checkout = self.open.get(checkout_id)
        if checkout is None:
            checkout = await self.store.call(lambda db: _read(db, checkout_id), fsync=False)
        if checkout is None or checkout.robot != self.robot:
            raise CheckoutError(404, f"no checkout {checkout_id} of robot {self.robot}")
        return checkout

    async def summaries(self) -> list[dict[str, object]]:
        def read(db: sqlite3.Connection) -> list[dict[str, object]]:
            ids = db.execute(
                "SELECT id FROM checkouts WHERE robot = ? ORDER BY id DESC", (self.robot,)
            ).fetchall()
            return [c.summary() for (row_id,) in ids if (c := _read(db, row_id)) is not None]

        return await self.store.call(read, fsync=False)

    async def save(self, checkout: Checkout, states: Iterable[PointState]) -> None:
        """The points' new states, committed durably."""
        rows = [
            (s.result, orjson.dumps(s.data()).decode(), checkout.id, s.point.key) for s in states
        ]
        if rows:
            await self.store.call(
                lambda db: db.executemany(
                    "UPDATE checkout_points SET result = ?, data = ? "
                    "WHERE checkout_id = ? AND key = ?",
                    rows,
                )
            )

    # ------------------------------------------------------------ actions

    async def capture(self, checkout: Checkout, key: str, value: float, at: float, by: str) -> None:
        state = checkout.open_point(key)
        if state.point.kind != "input" or state.point.signal != "analog":
            raise CheckoutError(
                409, f"{state.point.label} is not an analog input: only AI values are captured"
            )
        if len(state.samples) >= ANALOG_SAMPLES:
            state.samples = []  # a third capture starts the pair again
        state.samples.append({"time": at, "value": value, "by": by})
        if len(state.samples) == ANALOG_SAMPLES and state.result == "untested":
            state.result = "seen"
        elif len(state.samples) < ANALOG_SAMPLES and state.result == "seen":
            state.result = "untested"
        await self.save(checkout, [state])

    async def switched(
        self,
        checkout: Checkout,
        key: str,
        value: object,
        *,
        latency_ms: float | None,
        seq: int | None,
        by: str,
    ) -> None:
        """The robot confirmed the output ``key`` at ``value`` (a write that went through):
        the last switch, and one more in the point's evidence."""
        state = checkout.point(key)
        state.switched = {
            "time": time.time(),
            "value": value,
            "by": by,
            "latency_ms": latency_ms,
            "seq": seq,
        }
        state.switches.append(state.switched)
        await self.save(checkout, [state])

    async def record(
        self, checkout: Checkout, key: str, result: Result, comment: str, by: str
    ) -> PointState:
        state = checkout.open_point(key)
        p = state.point
        if result == "pass":
            if p.kind == "output" and state.switched is None:
                raise CheckoutError(
                    409,
                    f"{p.label}: switch it from the checkout first; a pass needs the robot "
                    "to have confirmed the output",
                )
            if p.signal == "digital":
                seen = state.seen is not None
            else:
                seen = len(state.samples) >= ANALOG_SAMPLES
            if p.kind == "input" and not seen:
                what = "its two captured values" if p.signal == "analog" else "its change"
                raise CheckoutError(
                    409, f"{p.label}: not seen yet; a pass needs {what} in the robot's frames"
                )
        elif result != "fail":
            raise CheckoutError(422, "a checker records pass or fail", "result")
        elif not comment.strip():
            raise CheckoutError(
                422, f"{p.label}: a fail needs a comment saying what is wrong", "comment"
            )
        state.result = result
        state.recorded = {"time": time.time(), "by": by, "comment": comment}
        await self.save(checkout, [state])
        return state

    async def close(self, checkout: Checkout, by: str) -> None:
        if checkout.closed:
            raise CheckoutError(409, f"checkout {checkout.id} is already closed")
        closed_at = time.time()
        await self.store.call(
            lambda db: db.execute(
                "UPDATE checkouts SET closed_at = ?, closed_by = ? WHERE id = ?",
                (closed_at, by, checkout.id),
            )
        )
        checkout.closed_at, checkout.closed_by = closed_at, by
        self.open.pop(checkout.id, None)


def _insert(
    db: sqlite3.Connection, robot: str, at: float, by: str, identity: dict[str, object] | None
) -> int:
    cursor = db.execute(
        "INSERT INTO checkouts (robot, started_at, started_by, identity) VALUES (?, ?, ?, ?)",
        (robot, at, by, None if identity is None else orjson.dumps(identity).decode()),
    )
    checkout_id = cursor.lastrowid
    assert checkout_id is not None
    empty = orjson.dumps(PointState(CHECK_POINTS[0]).data()).decode()
    db.executemany(
        "INSERT INTO checkout_points (checkout_id, key, result, data) VALUES (?, ?, ?, ?)",
        [(checkout_id, p.key, "untested", empty) for p in CHECK_POINTS],
    )
    return checkout_id


def _read(db: sqlite3.Connection, checkout_id: int) -> Checkout | None:
    row = db.execute(
        "SELECT robot, started_at, started_by, closed_at, closed_by, identity "
        "FROM checkouts WHERE id = ?",
        (checkout_id,),
    ).fetchone()
    if row is None:
        return None
    robot, started_at, started_by, closed_at, closed_by, identity = row
    checkout = Checkout(
        checkout_id,
        robot,
        started_at,
        started_by,
        None if identity is None else orjson.loads(identity),
        closed_at,
        closed_by,
    )
    stored = {
        key: (result, orjson.loads(data))
        for key, result, data in db.execute(
            "SELECT key, result, data FROM checkout_points WHERE checkout_id = ?", (checkout_id,)
        )
    }
    for p in CHECK_POINTS:  # layout order; a point the layout no longer has is left out
        result, data = stored.get(p.key, ("untested", {}))
        checkout.points[p.key] = PointState(
            p,
            result if result in RESULTS else "untested",
            data.get("seen"),
            list(data.get("samples") or []),
            data.get("switched"),
            _switches(data),
            data.get("recorded"),
        )
    return checkout


def _switches(data: dict[str, Any]) -> list[dict[str, Any]]:
    """A point's switches; a row written before they were kept has its last one only."""
    switches = data.get("switches")
    if isinstance(switches, list):
        return switches
    last = data.get("switched")
    return [last] if last else []
