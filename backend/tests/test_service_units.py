"""The service's pure parts: write validation and confirmation, events, the hub's queues and
decimation, and the SQLite store (durable commits, pages, CSV)."""

from __future__ import annotations

import asyncio
import csv
import io
import json
import sqlite3
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import orjson
import pytest

from cobot_hmi.codec import Frame, command_to_json, zero_command, zero_frame
from cobot_hmi.layout import FRAME_ECHOED
from cobot_hmi.service.events.bus import EventBus
from cobot_hmi.service.events.text import FrameWatcher
from cobot_hmi.service.robots.confirmation import FrameWaiters
from cobot_hmi.service.robots.frame_notifier import FrameNotifier, FrameRecord, LoopWake, Runs
from cobot_hmi.service.robots.watch import FrameEventWatch
from cobot_hmi.service.robots.websocket_fanout import (
    Kind,
    StreamClient,
    Subscription,
    WebSocketFanOut,
)
from cobot_hmi.service.storage.store import (
    AUDIT_COLUMNS,
    EVENT_COLUMNS,
    AuditEntry,
    Store,
    event_csv_rows,
    to_csv,
)
from cobot_hmi.service.writes.validation import (
    WriteValidationError,
    frame_shows,
    plan_write,
    robot_reports,
)
from waiting import eventually

# --------------------------------------------------------------------------- writes


def test_plan_write_applies_a_partial_image() -> None:
    base = zero_command()._replace(analog_output=(4.0, 0.0))
    body = {
        "controlbox_do": {"3": True},
        "tool_do": {"1": False},
        "analog_output": {"0": 12.5},
        "analog_output_type": {"0": 0},
        "bit_input_registers": {"40": True},
    }
    plan = plan_write(body, base)
    assert plan.image.controlbox_do[3] is True
    assert plan.image.analog_output[0] == 12.5
    assert plan.image.bit_input_registers[40] is True
    assert plan.field_names == [
        "controlbox_do.3",
        "tool_do.1",
        "analog_output_type.0",
        "analog_output.0",
        "bit_input_registers.40",
    ]
    assert plan.values(base)["analog_output.0"] == 4.0
    assert plan.by_packet == (("bit_input_registers", 40),)
    assert {"controlbox_do", "tool_do", "analog_output_type", "analog_output"} == FRAME_ECHOED


@pytest.mark.parametrize(
    ("body", "field", "reason"),
    [
        ({"controlbox_do": {"16": True}}, "controlbox_do.16", "out of range"),
        ({"controlbox_do": {"x": True}}, "controlbox_do", "not a whole number"),
        ({"tool_do": {"1": 1}}, "tool_do.1", "true or false"),
        ({"analog_output_type": {"0": 2}}, "analog_output_type.0", "0 to 1"),
        ({"analog_output": {"0": "12"}}, "analog_output.0", "a number"),
        ({"analog_output": {"0": None}}, "analog_output.0", "finite"),
        ({"analog_output": {"0": 25.0}}, "analog_output.0", "outside 4–20 mA"),
        ({"analog_output": {"1": 3.0}}, "analog_output.1", "outside 4–20 mA"),
        (
            {"analog_output_type": {"1": 1}, "analog_output": {"1": 10.5}},
            "analog_output.1",
            "0–10 V",
        ),
        ({"analog_output_type": {"0": 0}}, "analog_output.0", "together with the type change"),
        ({"speed": {"0": 1}}, "speed", "unknown field"),
        # Keys the T→O codec tolerates in a frame are not O→T fields (a 500 before).
        ({"extra": "00"}, "extra", "unknown field"),
        ({"robot_state_name": "X"}, "robot_state_name", "unknown field"),
        # A key str.isdigit() accepts but int() does not (a 500 before).
        ({"controlbox_do": {"²": True}}, "controlbox_do", ""),
        ({}, None, "nothing to write"),
        ([1, 2], None, "JSON object"),
    ],
)
def test_plan_write_rejects_with_the_field(body: object, field: str | None, reason: str) -> None:
    base = zero_command()  # both outputs: current, 0.0 (the robot's reset value)
    with pytest.raises(WriteValidationError) as caught:
        plan_write(body, base)
    assert caught.value.field == field
    assert reason in caught.value.reason


def test_voltage_range_after_type_change_in_the_same_request() -> None:
    plan = plan_write({"analog_output_type": {"1": 1}, "analog_output": {"1": 0.0}}, zero_command())
    assert plan.image.analog_output_type[1] == 1
    assert plan.image.analog_output[1] == 0.0


def test_frame_confirmation_and_report() -> None:
    plan = plan_write({"controlbox_do": {"2": True}, "analog_output": {"0": 12.5}}, zero_command())
    frame = zero_frame()
    assert not frame_shows(frame, plan.image, plan.by_frame)
    shown = frame._replace(controlbox_do=plan.image.controlbox_do, analog_output=(12.5000001, 0.0))
    assert frame_shows(shown, plan.image, plan.by_frame)
    off = shown._replace(analog_output=(13.0, 0.0))
    assert not frame_shows(off, plan.image, plan.by_frame)
    assert robot_reports(off, plan.by_frame) == {"controlbox_do.2": True, "analog_output.0": 13.0}
    assert robot_reports(None, plan.by_frame) == {"controlbox_do.2": None, "analog_output.0": None}


# --------------------------------------------------------------------------- events


def test_frame_watcher_reports_state_and_flag_changes() -> None:
    watcher = FrameWatcher()
    first = zero_frame()._replace(robot_state=13, servo_on=True)
    events = watcher.observe(first, 1.0)
    assert events == [
        {
            "kind": "robot_state",
            "time": 1.0,
            "from": None,
            "to": 13,
            "from_name": None,
            "to_name": "STANDALONE_STANDBY",
        }
    ]
    assert watcher.observe(first, 1.01) == []
    estop = first._replace(robot_state=0, servo_on=False, emergency_stopped=True)
    events = watcher.observe(estop, 2.0)
    assert [e["kind"] for e in events] == ["robot_state", "flag", "flag"]
    assert events[0]["to_name"] == "EMERGENCY_STOP"
    assert {(e["flag"], e["value"]) for e in events[1:]} == {
        ("servo_on", False),
        ("emergency_stopped", True),
    }
    assert watcher.observe(first._replace(robot_state=99), 3.0)[0]["to_name"] == "UNKNOWN"


# --------------------------------------------------------------------------- hub


async def _noop_abort(_: str) -> None:
    return None


class _Sink:
    """A client connection that records what it was sent (no network: queue logic only)."""

    def __init__(self) -> None:
        self.messages: list[Any] = []
        self.gate = asyncio.Event()
        self.gate.set()

    async def send(self, text: str) -> None:
        await self.gate.wait()
        self.messages.append(orjson.loads(text))


def test_stream_client_drops_oldest_frames_never_events() -> None:
    client = StreamClient(lambda _: asyncio.sleep(0), _noop_abort, Subscription(), max_frames=10)
    for i in range(5):
        client.offer(Kind.FRAMES, f"frames{i}", 4)
        client.offer(Kind.EVENT, f"event{i}")
    kinds = [(k, t) for k, t, _ in client.queue]
    assert (Kind.EVENT, "event0") in kinds
    assert [t for k, t in kinds if k is Kind.EVENT] == [f"event{i}" for i in range(5)]
    assert [t for k, t in kinds if k is Kind.FRAMES] == ["frames3", "frames4"]
    assert client.queued_frames == 8
    assert client.dropped_total == 12
    assert client.dropped_pending == 12
    client.offer(Kind.STATUS, "s1")
    client.offer(Kind.STATUS, "s2")
    assert [t for k, t, _ in client.queue if k is Kind.STATUS] == ["s2"]


class _NoAlarms:
    def observe(self, frame: Frame, time_s: float) -> list[dict[str, object]] | None:
        return None


def _fan_out(client_queue_frames: int) -> tuple[FrameNotifier, WebSocketFanOut]:
    """A robot's frames to its WebSocket fan-out, and its state events through an event bus,
    registered as the robot registers them; the test dispatches (``dispatch_now``) as the
    notifier would every five frames."""
    notifier = FrameNotifier("r", frames_per_wake=5)
    hub = WebSocketFanOut(
        robot="r", batch_s=0.05, client_queue_frames=client_queue_frames, stall_timeout_s=5
    )
    bus = EventBus()
    bus.add(hub)
    notifier.add(hub)
    notifier.add(FrameEventWatch(_NoAlarms(), lambda events: bus.publish("r", *events)))
    return notifier, hub


async def test_hub_batches_decimates_and_tells_about_drops() -> None:
    notifier, hub = _fan_out(1000)
    full, slow = _Sink(), _Sink()
    a = hub.add_client(full.send, _noop_abort, None, {"type": "hello"})
    b = hub.add_client(slow.send, _noop_abort, 20.0, {"type": "hello"})
    frame = zero_frame()
    for i in range(100):  # one second of frames at 10 ms
        notifier.publish(frame._replace(robot_state=i % 3), b"", 1000.0 + i * 0.01, i)
        if i % 5 == 4:
            notifier.dispatch_now()
    for _ in range(20):
        await asyncio.sleep(0)
    full_frames = [f for m in full.messages if m["type"] == "frames" for f in m["frames"]]
    slow_frames = [f for m in slow.messages if m["type"] == "frames" for f in m["frames"]]
    assert full.messages[0] == {"type": "hello"}
    assert [f["seq"] for f in full_frames] == list(range(1, 101))
    assert sum(1 for m in full.messages if m["type"] == "frames") == 20  # 5 frames per message
    assert 19 <= len(slow_frames) <= 21  # 20 Hz out of 100 Hz
    assert full_frames[0]["frame"]["robot_state_name"] == "EMERGENCY_STOP"
    events = [m["event"] for m in full.messages if m["type"] == "event"]
    assert any(e["kind"] == "robot_state" for e in events)
    assert a.frames_sent == 100
    await hub.remove_client(b)
    # A client that cannot keep up: its queue overflows and it is told how much it lost.
    small_frames, small = _fan_out(10)
    blocked = _Sink()
    blocked.gate.clear()
    small.add_client(blocked.send, _noop_abort, None, {"type": "hello"})
    for i in range(40):
        small_frames.publish(frame, b"", 1000.0 + i * 0.01, i)
        if i % 5 == 4:
            small_frames.dispatch_now()
    blocked.gate.set()
    for _ in range(20):
        await asyncio.sleep(0)
    dropped = [m["count"] for m in blocked.messages if m["type"] == "dropped"]
    got = [f["seq"] for m in blocked.messages if m["type"] == "frames" for f in m["frames"]]
    assert sum(dropped) + len(got) == 40
    assert sum(dropped) > 0
    assert got == sorted(got)
    await hub.close()
    await small.close()


async def test_a_write_waits_for_the_first_frame_that_shows_it() -> None:
    loop = asyncio.get_running_loop()
    notifier = FrameNotifier("r", frames_per_wake=50)  # a broadcast period of 50 frames
    notifier.bind_loop(loop)
    waiters = FrameWaiters(notifier)
    after = notifier.seq
    waiting = asyncio.create_task(waiters.wait_for_frame(lambda f: f.robot_state == 5, after, 30.0))
    await asyncio.sleep(0)
    # Urgent while it waits: the second frame confirms it, not the 50th.
    loop.call_soon(notifier.publish, zero_frame(), b"", 1.0, 1)
    loop.call_soon(notifier.publish, zero_frame()._replace(robot_state=5), b"", 1.01, 2)
    record = await waiting
    assert record is not None
    assert record.seq == 2 and record.frame.robot_state == 5
    assert await waiters.wait_for_frame(lambda f: f.robot_state == 7, notifier.seq, 0.05) is None
    waiters.close()


class _LoopConsumer:
    """A loop consumer that keeps the sequence numbers of every batch it is handed."""

    name = "test"
    runs = Runs.LOOP
    queue_frames = 100

    def __init__(self) -> None:
        self.batches: list[list[int]] = []

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        self.batches.append([record.seq for record in records])


def _two_robots(
    turn_period_s: float | None = None,
) -> tuple[FrameNotifier, FrameNotifier, _LoopConsumer, _LoopConsumer]:
    """Two robots' notifiers (a broadcast period of 5 frames) bound to this test's loop, each
    with a loop consumer that keeps its batches."""
    loop = asyncio.get_running_loop()
    left = FrameNotifier("left", frames_per_wake=5, turn_period_s=turn_period_s)
    right = FrameNotifier("right", frames_per_wake=5, turn_period_s=turn_period_s)
    left_seen, right_seen = _LoopConsumer(), _LoopConsumer()
    left.add(left_seen)
    right.add(right_seen)
    left.bind_loop(loop)
    right.bind_loop(loop)
    return left, right, left_seen, right_seen


async def test_the_robots_of_one_loop_share_one_wake() -> None:
    """The first robot to have a broadcast period of frames wakes the loop once, and every
    robot's consumers take their frames then: one turn of the loop for the cell."""
    left, right, left_seen, right_seen = _two_robots()
    for i in range(3):
        right.publish(zero_frame(), b"", 1000.0 + i * 0.01, i)
    for i in range(5):
        left.publish(zero_frame(), b"", 1000.0 + i * 0.01, i)
    await eventually(lambda: bool(left_seen.batches))
    assert left_seen.batches == [[1, 2, 3, 4, 5]]
    assert right_seen.batches == [[1, 2, 3]], "served in the same turn, before its own 5"
    for i in range(4):  # both start counting again after the turn
        right.publish(zero_frame(), b"", 1000.1 + i * 0.01, i)
    for _ in range(20):
        await asyncio.sleep(0)
    assert right_seen.batches == [[1, 2, 3]]
    right.publish(zero_frame(), b"", 1000.2, 9)
    await eventually(lambda: len(right_seen.batches) == 2)
    assert right_seen.batches[1] == [4, 5, 6, 7, 8]
    assert left_seen.batches == [[1, 2, 3, 4, 5]], "nothing new: no empty batch"


async def test_a_broadcast_period_is_the_loop_timers_not_the_first_robots() -> None:
    """With a ``turn_period_s`` the loop's timer serves the cell: a robot with a broadcast
    period of frames (5) does not ask for a turn of its own, every robot's frames are taken in
    the timer's turn, and a robot asks itself only at twice its period's frames (the timer
    behind)."""
    left, right, left_seen, right_seen = _two_robots(3600.0)  # the timer far off
    for i in range(3):
        right.publish(zero_frame(), b"", 1000.0 + i * 0.01, i)
    for i in range(9):
        left.publish(zero_frame(), b"", 1000.0 + i * 0.01, i)
    for _ in range(20):
        await asyncio.sleep(0)
    assert left_seen.batches == [] and right_seen.batches == [], "no turn asked at 5 frames"
    left.publish(zero_frame(), b"", 1000.1, 9)  # the tenth: the timer is behind
    await eventually(lambda: bool(left_seen.batches))
    assert left_seen.batches == [list(range(1, 11))]
    assert right_seen.batches == [[1, 2, 3]], "served in the same turn"


async def test_the_loop_timer_turns_on_its_period() -> None:
    """A short period: frames fewer than a period's are taken by the timer's turns, the cell's
    robots in the same turn; turns keep coming while nothing is published (no empty batch)."""
    left, right, left_seen, right_seen = _two_robots(0.01)
    wake = LoopWake.of(asyncio.get_running_loop())
    left.publish(zero_frame(), b"", 1000.0, 0)
    right.publish(zero_frame(), b"", 1000.0, 0)
    right.publish(zero_frame(), b"", 1000.01, 1)
    await eventually(lambda: bool(left_seen.batches) and bool(right_seen.batches))
    assert left_seen.batches == [[1]] and right_seen.batches == [[1, 2]]
    turns = wake.timed_turns
    await eventually(lambda: wake.timed_turns >= turns + 3)
    assert left_seen.batches == [[1]], "nothing new: no empty batch"
    left.publish(zero_frame(), b"", 1000.1, 1)
    await eventually(lambda: len(left_seen.batches) == 2)
    assert left_seen.batches[1] == [2]


# --------------------------------------------------------------------------- store


async def test_store_audit_and_events(tmp_path: Path) -> None:
    store = Store(tmp_path / "db" / "hmi.db")
    await store.open()
    try:
        row = await store.add_audit(
            AuditEntry(
                "alice",
                "127.0.0.1",
                "write",
                ["controlbox_do.3"],
                {"controlbox_do.3": False},
                {"controlbox_do.3": True},
                "pending",
                None,
            )
        )
        # Committed before the call returned: another connection sees it at once.
        with sqlite3.connect(tmp_path / "db" / "hmi.db") as other:
            assert other.execute("SELECT outcome FROM audit WHERE id = ?", (row,)).fetchone() == (
                "pending",
            )
            assert other.execute("PRAGMA journal_mode").fetchone() == ("wal",)
        await store.finish_audit(row, "confirmed", None)
        for i in range(3):
            await store.add_audit(
                AuditEntry("bob", None, "control.take", [], None, None, "refused", f"r{i}")
            )
        page = await store.audit_page(2, 0)
        assert page.total == 4
        assert [item["reason"] for item in page.items] == ["r2", "r1"]
        last = (await store.audit_page(10, 3)).items
        assert last[0]["outcome"] == "confirmed"
        assert last[0]["requested"] == {"controlbox_do.3": True}
        text = to_csv(last, AUDIT_COLUMNS)
        rows = list(csv.reader(io.StringIO(text)))
        assert rows[0] == list(AUDIT_COLUMNS)
        assert rows[1][AUDIT_COLUMNS.index("fields")] == '["controlbox_do.3"]'

        for i in range(50):
            store.submit_event(float(i), "flag" if i % 2 else "robot_state", {"i": i})
        await store.flush_events()
        events = await store.events_page("flag", 5, 0)
        assert events.total == 25
        assert [e["i"] for e in events.items][:2] == [49, 47]
        assert events.items[0]["kind"] == "flag" and events.items[0]["time"] == 49.0
        assert (await store.events_page(None, 1, 0)).total == 50
    finally:
        await store.close()
    assert command_to_json(zero_command())  # the codec's JSON form is what the store keeps


async def test_store_events_and_audit_by_robot(tmp_path: Path) -> None:
    store = Store(tmp_path / "hmi.db")
    await store.open()
    try:
        for robot in ("left", "right", "left"):
            store.log_event(
                {"kind": "flag", "time": 1.0, "robot": robot, "flag": "servo_on", "value": True}
            )
            await store.add_audit(
                AuditEntry(
                    "alice", None, "write", [], None, None, "invalid", "x", robot=robot, origin="t"
                )
            )
        await store.flush_events()
        left = await store.events_page(None, 10, 0, robot="left")
        assert left.total == 2
        assert left.items[0] == {
            "id": 3,
            "time": 1.0,
            "robot": "left",
            "kind": "flag",
            "flag": "servo_on",
            "value": True,
        }
        assert (await store.events_page("flag", 10, 0, robot="right")).total == 1
        assert (await store.events_page("write", 10, 0, robot="right")).total == 0
        audit = await store.audit_page(10, 0, robot="right")
        assert audit.total == 1
        assert audit.items[0]["robot"] == "right" and audit.items[0]["origin"] == "t"
        rows = list(csv.DictReader(io.StringIO(to_csv(event_csv_rows(left.items), EVENT_COLUMNS))))
        assert rows[0]["robot"] == "left"
        assert json.loads(rows[0]["data"]) == {"flag": "servo_on", "value": True}
    finally:
        await store.close()


async def test_store_migrates_a_database_without_robot_columns(tmp_path: Path) -> None:
    path = tmp_path / "old.db"
    with sqlite3.connect(path) as old:  # the schema of the first release
        old.executescript(
            "CREATE TABLE audit (id INTEGER PRIMARY KEY AUTOINCREMENT, time REAL NOT NULL,"
            " user TEXT, client TEXT, action TEXT NOT NULL, fields TEXT NOT NULL, before TEXT,"
            " requested TEXT, outcome TEXT NOT NULL, reason TEXT);"
            "CREATE TABLE events (id INTEGER PRIMARY KEY AUTOINCREMENT, time REAL NOT NULL,"
            " kind TEXT NOT NULL, data TEXT NOT NULL);"
            "INSERT INTO audit (time, user, action, fields, outcome) VALUES"
            " (1.0, 'alice', 'control.take', '[]', 'granted');"
            "INSERT INTO events (time, kind, data) VALUES (2.0, 'flag', '{\"value\": true}');"
        )
    old.close()
    store = Store(path)
    await store.open()
    try:
        audit = await store.audit_page(10, 0)
        assert audit.total == 1
        assert audit.items[0]["user"] == "alice" and audit.items[0]["robot"] is None
        events = await store.events_page(None, 10, 0)
        assert events.items == [
            {"id": 1, "time": 2.0, "robot": None, "kind": "flag", "value": True}
        ]
        await store.add_audit(
            AuditEntry("bob", None, "write", [], None, None, "invalid", None, robot="a")
        )
        assert (await store.audit_page(10, 0, robot="a")).total == 1
        assert (await store.audit_page(10, 0)).total == 2
    finally:
        await store.close()


async def test_each_frame_is_serialized_once_whatever_the_clients(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import cobot_hmi.service.robots.websocket_fanout as hub_module
    from cobot_hmi.codec import frame_to_json as real

    calls = 0

    def counting(frame: Any) -> dict[str, object]:
        nonlocal calls
        calls += 1
        return real(frame)

    monkeypatch.setattr(hub_module, "frame_to_json", counting)
    notifier, hub = _fan_out(1000)
    sinks = [_Sink() for _ in range(6)]
    for i, sink in enumerate(sinks):  # three rate groups: every frame, 50 Hz, 20 Hz
        hub.add_client(sink.send, _noop_abort, (None, 50.0, 20.0)[i % 3], {"type": "hello"})
    # Frames change every fifth packet: the robot's bytes (and so the originator's Frame
    # object) stay the same in between, as a robot refreshes its values every 100 ms.
    frames = [zero_frame()._replace(robot_state=i // 5) for i in range(0, 50, 5)]
    for i in range(50):
        notifier.publish(frames[i // 5], b"", 1000.0 + i * 0.01, i)
        if i % 5 == 4:
            notifier.dispatch_now()
    for _ in range(20):
        await asyncio.sleep(0)
    assert calls == 10  # once per frame object, not per packet, client or rate group
    counts = [sum(len(m["frames"]) for m in s.messages if m["type"] == "frames") for s in sinks]
    assert counts[0] == counts[3] == 50
    assert counts[1] == counts[4] < 50
    assert counts[2] == counts[5] < counts[1]
    await hub.close()
