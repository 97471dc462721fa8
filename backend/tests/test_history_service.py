"""History against the real emulator and service: a recorded minute equals the frames the scanner
saw (wire sequence numbers, counters, times, every element), the REST history answer equals a
brute-force decimation of the recorded rows, exports read back by independent readers, refusals
say what is wrong, and a disk that cannot be written pauses recording with an event while the
service keeps serving."""

from __future__ import annotations

import asyncio
import csv
import io
import itertools
import math
import re
import time
from collections.abc import Mapping
from datetime import datetime
from pathlib import Path
from typing import Any

import httpx
import orjson
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from mcap.reader import make_reader
from websockets.asyncio.client import connect

from cobot_hmi.emulator.robot import RobotSettings as SimulationSettings
from cobot_hmi.emulator.robot import SimulatedRobot
from cobot_hmi.history import segments
from cobot_hmi.history.query import CELL_S, bucket_grid
from cobot_hmi.history.schema import (
    ELEMENT_BY_EXPORT_NAME,
    ELEMENTS,
    Element,
    raw_from_columns,
    time_seconds,
)
from cobot_hmi.settings import HmiSettings
from conftest import _next_host
from service_support import (
    DEADLINE_S,
    OPERATOR,
    Running,
    cell_settings,
    emulator,
    eventually,
    running_service,
    service_settings,
)
from test_history_storage import brute_force, f32, same

pytestmark = pytest.mark.timeout(180)

ROBOT = "robot"


def simulated() -> SimulatedRobot:
    """The simulation with fresh monitoring values in every frame (all of them differ)."""
    return SimulatedRobot(SimulationSettings(kinematic_refresh_ms=0.0))


async def stream_frames(hmi: Running, count: int) -> list[dict[str, Any]]:
    """``count`` frames as the robot's WebSocket stream delivers them (``seq``, ``t``, frame)."""
    seen: list[dict[str, Any]] = []
    async with connect(hmi.robot_ws_url(ROBOT), max_size=None) as ws:
        while len(seen) < count:
            message = orjson.loads(await asyncio.wait_for(ws.recv(), DEADLINE_S))
            if message["type"] == "frames":
                seen.extend(message["frames"])
    return seen


async def wait_recorded(client: httpx.AsyncClient, from_s: float, last_seq: int) -> None:
    """Until the recording holds frame ``last_seq`` (the recorder flushes every 0.2 s here)."""
    for _ in range(int(DEADLINE_S * 10)):
        answer = await client.get(
            f"/api/v1/robots/{ROBOT}/history",
            params={"from": from_s, "to": from_s + 3600, "points": 5000, "fields": "robot_state"},
        )
        assert answer.status_code == 200, answer.text
        body = answer.json()
        if body["mode"] == "buckets" or (body["seq"] and body["seq"][-1] >= last_seq):
            return  # (buckets: more than 5000 frames recorded since ``from_s``)
        await asyncio.sleep(0.1)
    raise AssertionError(f"frame {last_seq} not recorded in time")


def first_difference(
    got: list[tuple[Any, ...]], expected: list[tuple[Any, ...]], edges: list[tuple[float, float]]
) -> str:
    """Where an answer's buckets first differ from the brute force's, for a failure's message."""
    for i, (a, b) in enumerate(zip(got, expected, strict=False)):
        if not same([a], [b]):
            return f"bucket {i} of {len(edges)} {edges[i] if i < len(edges) else ''}: {a} != {b}"
    return f"{len(got)} buckets answered, {len(expected)} expected"


def as_recorded(table: pa.Table) -> pa.Table:
    """An export's table with the recording's column names (``joint_position.J1`` is
    ``joint_position.0``), to compare with the API's element keys."""
    return table.rename_columns(
        [
            ELEMENT_BY_EXPORT_NAME[n].name if n in ELEMENT_BY_EXPORT_NAME else n
            for n in table.column_names
        ]
    )


def element_value(frame: Mapping[str, Any], element: Element) -> object:
    """An element's value in the stream's frame JSON."""
    value = frame[element.field.name]
    if element.field.scalar:
        return value
    if element.field.element_names:
        return value[element.field.element_names[element.index]]
    return value[element.index]


def history_settings(
    target_port: int, robot_host: str, plc_host: str, tmp_path: Path, **extra: Any
) -> HmiSettings:
    """Segments of 2 s and flushes every 0.2 s (unless ``extra`` says otherwise)."""
    return service_settings(
        robot_host,
        target_port,
        plc_host,
        tmp_path,
        **{"history_segment_s": 2.0, "history_flush_s": 0.2, **extra},
    )


RECORDED_S = 60.0
"""The span the issue names: "a recorded minute" (6000 frames at the service's 10 ms RPI)."""


async def stream_span(hmi: Running, span_s: float) -> tuple[list[dict[str, Any]], int]:
    """The robot's WebSocket stream until its frames span ``span_s`` of receive time: the frames
    (``seq``, ``t``, ``t2o_sequence``, frame) and how many between them the stream said this
    client missed (``dropped``: it read too slowly; never on a quiet machine)."""
    seen: list[dict[str, Any]] = []
    dropped = 0
    async with connect(hmi.robot_ws_url(ROBOT), max_size=None) as ws:
        while not seen or seen[-1]["t"] - seen[0]["t"] < span_s:
            message = orjson.loads(await asyncio.wait_for(ws.recv(), DEADLINE_S))
            if message["type"] == "frames":
                seen.extend(message["frames"])
            elif message["type"] == "dropped" and seen:
                dropped += message["count"]
    return seen, dropped


async def wait_frame_recorded(client: httpx.AsyncClient, t: float, seq: int) -> None:
    """Until the recording holds frame ``seq`` received at ``t`` (a second's range around it
    is always answered raw)."""
    for _ in range(int(DEADLINE_S * 10)):
        answer = await client.get(
            f"/api/v1/robots/{ROBOT}/history",
            params={"from": t - 0.5, "to": t + 0.5, "points": 5000, "fields": "robot_state"},
        )
        assert answer.status_code == 200, answer.text
        body = answer.json()
        assert body["mode"] == "raw"
        if seq in (body["seq"] or []):
            return
        await asyncio.sleep(0.1)
    raise AssertionError(f"frame {seq} not recorded in time")


def metric(metrics: str, name: str) -> float:
    found = re.search(rf'cobot_hmi_{name}{{robot="{ROBOT}"}} (\S+)', metrics)
    assert found, name
    return float(found[1])


@pytest.mark.timeout(420)
async def test_a_recorded_minute_equals_the_frames_the_scanner_saw(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    """A minute of the robot's stream against the recording of that minute: the same wire
    sequence numbers (each frame's T→O packet's own), one after the other except where the
    scanner counted packets it did not deliver; the same receive times and every element's
    value; and no frame lost between the scanner and the disk (the service's counter ``seq``
    has no gap)."""
    async with emulator(robot_host, simulated()) as target:
        settings = history_settings(target.tcp_port, robot_host, plc_host, tmp_path)
        async with running_service(settings) as hmi:
            seen, dropped = await stream_span(hmi, RECORDED_S)
            async with hmi.client() as client:
                await wait_frame_recorded(client, seen[-1]["t"], seen[-1]["seq"])
                export = await client.get(
                    f"/api/v1/robots/{ROBOT}/export",
                    params={
                        "from": seen[0]["t"] - 0.001,
                        "to": seen[-1]["t"] + 0.001,
                        "format": "parquet",
                    },
                )
            metrics = await hmi.metrics()
    assert export.status_code == 200, export.text
    table = as_recorded(pq.read_table(pa.BufferReader(export.content)))
    seqs = table.column("seq").to_pylist()
    first, last = seqs.index(seen[0]["seq"]), seqs.index(seen[-1]["seq"])
    table = table.slice(first, last - first + 1)
    seqs = seqs[first : last + 1]
    wires = table.column("t2o_sequence").to_pylist()
    # A minute recorded, every frame of it: none lost after the scanner, none twice.
    assert seqs == list(range(seen[0]["seq"], seen[-1]["seq"] + 1))
    assert len(seqs) == len(seen) + dropped
    # The wire's numbers, one per packet: a step of more than one only where the scanner
    # counted packets it did not deliver (lost, or no new data), over the whole connection.
    assert None not in wires
    steps = [(b - a) & 0xFFFF_FFFF for a, b in itertools.pairwise(wires)]
    assert min(steps) >= 1
    # A new connection numbers its packets afresh (a loaded machine's stall past the timeout
    # reconnects): one step of any size, back or forward, where the connection came up again.
    reconnects = round(metric(metrics, "connects_total")) - 1
    ordinary = sorted(steps)[: len(steps) - reconnects]
    assert max(ordinary) < 1 << 31, "no step back within a connection"
    undelivered = metric(metrics, "frame_gaps_total") + metric(metrics, "frame_duplicates_total")
    assert sum(step - 1 for step in ordinary) <= undelivered
    # Each frame the stream showed is the recorded row of its wire number: time and values.
    rows = {wire: i for i, wire in enumerate(wires)}
    assert len(rows) == len(wires)
    times = time_seconds(table)
    columns = {e.name: table.column(e.name).to_pylist() for e in ELEMENTS}
    for item in seen:
        row = rows[item["t2o_sequence"]]
        assert seqs[row] == item["seq"]
        assert times[row] == pytest.approx(item["t"], abs=1e-6)
        for e in ELEMENTS:
            expected = element_value(item["frame"], e)
            actual = columns[e.name][row]
            if expected is None:  # a non-finite REAL is null in JSON
                assert actual is not None and not math.isfinite(actual), e.name
            else:
                assert actual == expected, (item["t2o_sequence"], e.name)
    # Segments were closed on the way (2 s each), and the recorder lost nothing.
    assert len(list((tmp_path / "history" / ROBOT).glob("*-*.cells.arrow"))) >= 10
    assert metric(metrics, "history_frames_dropped_total") == 0
    assert re.search(r"cobot_hmi_history_recording 1.0", metrics)
    assert metric(metrics, "history_frames_recorded_total") >= len(seqs)


async def test_history_answer_equals_brute_force_over_the_recorded_rows(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    names = ["joint_position.1", "joint_torque.4", "robot_state", "servo_on"]
    async with emulator(robot_host, simulated()) as target:
        settings = history_settings(target.tcp_port, robot_host, plc_host, tmp_path)
        async with running_service(settings) as hmi:
            seen = await stream_frames(hmi, 400)
            from_s, to_s = seen[0]["t"], seen[-1]["t"]
            # The coarsest answer's buckets are whole seconds up to the grid's end, past to_s:
            # recorded to there before asking (else the export, read later, holds more).
            end_cell = bucket_grid(from_s, to_s, (to_s - from_s) / 2).end_cell
            hub = hmi.service.robot(ROBOT).frames
            await eventually(lambda: hub.latest is not None and hub.latest[1] >= end_cell)
            assert hub.latest is not None
            async with hmi.client() as client:
                await wait_recorded(client, from_s, hub.latest[0])
                answers = {}
                for points in (5000, 40, 2):
                    answer = await client.get(
                        f"/api/v1/robots/{ROBOT}/history",
                        params={
                            "from": from_s,
                            "to": to_s,
                            "points": points,
                            "fields": "joint_position.1,joint_torque.4,robot_state,servo_on",
                        },
                    )
                    assert answer.status_code == 200, answer.text
                    answers[points] = answer.json()
                # Whole-second cells need a range of seconds: the wider, the more cells.
                grid = bucket_grid(from_s, to_s, (to_s - from_s) / 2)
                export = await client.get(
                    f"/api/v1/robots/{ROBOT}/export",
                    params={
                        "from": grid.first_cell,
                        "to": grid.end_cell,
                        "format": "parquet",
                        "fields": ",".join(names),
                    },
                )
    table = as_recorded(pq.read_table(pa.BufferReader(export.content)))
    t = time_seconds(table)
    raw = answers[5000]
    assert raw["mode"] == "raw"
    inside = (t >= from_s) & (t < to_s)
    assert raw["seq"] == [
        s for s, keep in zip(table.column("seq").to_pylist(), inside, strict=True) if keep
    ]
    assert raw["t2o_sequence"] == [
        w for w, keep in zip(table.column("t2o_sequence").to_pylist(), inside, strict=True) if keep
    ]
    for points in (40, 2):
        body = answers[points]
        assert body["mode"] == "buckets"
        width = (to_s - from_s) / points
        if width >= CELL_S:
            grid = bucket_grid(from_s, to_s, width)
            bucket_s, first, end = grid.bucket_s, grid.first_cell, grid.end_cell
            edges = [(float(b), float(b + bucket_s)) for b in range(first, end, bucket_s)]
            rows = table
        else:
            edges = [(from_s + k * width, from_s + (k + 1) * width) for k in range(points)]
            edges[-1] = (edges[-1][0], to_s)
            rows = table.filter(pa.array(inside))
        assert body["frames"] == rows.num_rows
        for name in names:
            series = next(s for s in body["series"] if s["element"] == name)
            got = [
                (c, *(series[s][i] for s in ("min", "max", "first", "last")))
                for i, c in enumerate(body["count"])
            ]
            expected = [tuple(_json(v) for v in row) for row in brute_force(rows, name, edges)]
            assert same(got, expected), (points, name, first_difference(got, expected, edges))


def _json(value: object) -> object:
    """As JSON carries it: a float32 through orjson is its shortest text, read as a double."""
    if isinstance(value, float) and math.isfinite(value):
        import numpy as np

        return float(repr(np.float32(value)).removeprefix("np.float32(").removesuffix(")"))
    return value


async def test_exports_read_back_by_independent_readers(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    robot = simulated()
    async with emulator(robot_host, robot) as target:
        settings = history_settings(target.tcp_port, robot_host, plc_host, tmp_path)
        async with running_service(settings) as hmi:
            started = hmi.service.started_at
            seen = await stream_frames(hmi, 100)
            # An emergency stop: its alarm goes into the events channel beside the frames.
            robot.estop(time.time())
            for _ in range(int(DEADLINE_S * 10)):
                seen += await stream_frames(hmi, 10)
                if seen[-1]["frame"]["robot_state"] == 0:
                    break
            else:
                raise AssertionError("the emergency stop never showed")
            seen += await stream_frames(hmi, 10)
            async with hmi.client() as client:
                await wait_recorded(client, seen[0]["t"], seen[-1]["seq"])
                await hmi.service.store.flush_events()
                params = {"from": started - 5, "to": seen[-1]["t"] + 0.001}
                csv_answer = await client.get(
                    f"/api/v1/robots/{ROBOT}/export",
                    params={**params, "format": "csv", "fields": "joint_position,robot_state"},
                )
                mcap_answer = await client.get(
                    f"/api/v1/robots/{ROBOT}/export", params={**params, "format": "mcap"}
                )
    assert csv_answer.status_code == 200
    assert csv_answer.headers["content-type"].startswith("text/csv")
    disposition = csv_answer.headers["content-disposition"]
    assert re.fullmatch(
        rf'attachment; filename="{ROBOT}_\d{{8}}T\d{{6}}Z_\d{{8}}T\d{{6}}Z\.csv"', disposition
    )
    # The text as docs/api.md shows it: names and times quoted, numbers and bits not.
    header, first_row = csv_answer.text.splitlines()[:2]
    assert header.startswith('"time","seq","t2o_sequence","joint_position.J1 [degree]",')
    assert header.endswith(',"joint_position.J6 [degree]","robot_state"')
    assert re.fullmatch(
        r'"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z",\d+,\d+(,-?[\d.e+-]+){6},\d+', first_row
    ), first_row
    rows = list(csv.reader(io.StringIO(csv_answer.text)))
    assert rows[0] == [
        "time",
        "seq",
        "t2o_sequence",
        *(f"joint_position.J{i} [degree]" for i in range(1, 7)),
        "robot_state",
    ]
    by_seq = {int(r[1]): r for r in rows[1:]}
    for item in seen:
        row = by_seq[item["seq"]]
        assert datetime.fromisoformat(row[0]).timestamp() == pytest.approx(item["t"], abs=1e-6)
        assert int(row[2]) == item["t2o_sequence"]
        assert int(row[9]) == item["frame"]["robot_state"]
    assert mcap_answer.status_code == 200
    reader = make_reader(io.BytesIO(mcap_answer.content))
    frames, events = {}, []
    for schema, channel, message in reader.iter_messages():
        data = orjson.loads(message.data)
        if channel.topic == f"/{ROBOT}/frames":
            assert schema is not None and schema.encoding == "jsonschema"
            frames[data["seq"]] = data
        else:
            assert channel.topic == f"/{ROBOT}/events"
            events.append(data)
    for item in seen:
        message = frames[item["seq"]]
        assert message["t2o_sequence"] == item["t2o_sequence"]
        for name, value in item["frame"].items():
            if name.endswith("_name"):
                continue
            assert f32(message[name]) == f32(value), name
    # The connection coming up is on the same time axis, in its own channel; so is the
    # emergency stop's alarm, at the first frame that showed it.
    assert any(e["kind"] == "connection" and e["state"] == "connected" for e in events)
    # The first recorded frame in state 0: the stream may have skipped it (a busy client is
    # sent the newest frame, not every one); the recording holds them all.
    recorded = sorted(rows[1:], key=lambda r: int(r[1]))
    first_stopped = next(r for r in recorded if int(r[9]) == 0)
    stopped_at = datetime.fromisoformat(first_stopped[0]).timestamp()
    alarms = [e for e in events if e["kind"] == "alarm"]
    estop = [e for e in alarms if e["alarm"]["key"] == "emergency_stop"]
    assert [e["transition"] for e in estop] == ["activated"], alarms
    assert estop[0]["time"] == pytest.approx(stopped_at, abs=1e-6)
    assert estop[0]["alarm"]["priority"] == "critical" and estop[0]["robot"] == ROBOT
    times = [e["time"] for e in events]
    assert times == sorted(times)


async def test_refusals_name_the_parameter(robot_host: str, plc_host: str, tmp_path: Path) -> None:
    async with emulator(robot_host) as target:
        settings = history_settings(target.tcp_port, robot_host, plc_host, tmp_path)
        async with running_service(settings) as hmi, hmi.client() as client:
            path = f"/api/v1/robots/{ROBOT}/history"
            cases = [
                (path, {"from": "yesterday", "to": "1"}, 422, "from"),
                (path, {"from": "10", "to": "5"}, 422, "to"),
                (path, {"from": "10", "to": "20", "fields": "joint_positon"}, 422, "fields"),
                (path, {"from": "10", "to": "20", "points": "5001"}, 422, "points"),
                (path, {"to": "20"}, 422, "from"),
                ("/api/v1/robots/nobody/history", {"from": "1", "to": "2"}, 404, "name"),
                (
                    f"/api/v1/robots/{ROBOT}/export",
                    {"from": "1", "to": "2", "format": "xlsx"},
                    422,
                    "format",
                ),
            ]
            for url, params, status, field in cases:
                answer = await client.get(url, params=params)
                assert answer.status_code == status, (params, answer.text)
                assert answer.json()["detail"]["field"] == field, (params, answer.text)
            # ISO 8601 and epoch seconds are the same range; an empty range is an empty answer.
            iso = await client.get(
                path, params={"from": "2001-01-01T00:00:00Z", "to": "2001-01-01T01:00:00+01:00"}
            )
            epoch = await client.get(path, params={"from": "978307200", "to": "978307200.5"})
            assert iso.status_code == 422  # 01:00+01:00 is the same instant: an empty range
            assert epoch.status_code == 200
            assert epoch.json()["frames"] == 0 and epoch.json()["mode"] == "raw"


async def test_unwritable_disk_pauses_recording_and_the_service_keeps_running(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    # Running as root here, so a read-only directory would not stop a write: the history
    # directory is made impossible instead (a regular file where its parent must be), which
    # fails every write with an OSError as a full or failed disk does.
    blocker = tmp_path / "blocked"
    blocker.write_bytes(b"not a directory")
    history_dir = blocker / "history"
    async with emulator(robot_host) as target:
        settings = history_settings(
            target.tcp_port, robot_host, plc_host, tmp_path, history_dir=history_dir
        )
        async with running_service(settings) as hmi:
            async with hmi.client(await hmi.login(OPERATOR)) as client:
                events = await _wait_event(client, "paused")
                assert "cannot write" in events[0]["reason"]
                # The robot's built-in alarm, high priority, for the banner and the cue.
                alarm = await _recording_alarm(client, active=True)
                assert alarm["priority"] == "high" and alarm["kind"] == "recording"
                assert alarm["state"] == "active_unacknowledged"
                assert alarm["name"] == "Recording paused: disk full"
                assert "cannot write" in alarm["message"]
                # The service keeps serving frames and the stream.
                frame = await client.get(f"/api/v1/robots/{ROBOT}/frame")
                assert frame.status_code == 200 and frame.json()["frame"] is not None
                await stream_frames(hmi, 20)
                assert "cobot_hmi_history_recording 0.0" in await hmi.metrics()
                # The disk comes back: recording resumes by itself.
                blocker.unlink()
                blocker.mkdir()
                events = await _wait_event(client, "recording")
                assert events[0]["reason"] == "recording resumed"
                # The alarm returns to normal; unacknowledged, it waits for an operator.
                alarm = await _recording_alarm(client, active=False)
                assert alarm["state"] == "returned_unacknowledged"
                assert alarm["message"] == "recording resumed"
                seen = await stream_frames(hmi, 50)
                await wait_recorded(client, seen[0]["t"], seen[-1]["seq"])
            metrics = await hmi.metrics()
    assert "cobot_hmi_history_recording 1.0" in metrics
    assert re.search(
        rf'cobot_hmi_history_frames_not_recorded_total{{robot="{ROBOT}"}} [1-9]', metrics
    )


async def test_low_free_space_pauses_recording(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    # The other trigger: free space under history_min_free_bytes (here more than any disk has).
    async with emulator(robot_host) as target:
        settings = history_settings(
            target.tcp_port, robot_host, plc_host, tmp_path, history_min_free_bytes=2**62
        )
        async with running_service(settings) as hmi:
            client = hmi.client(await hmi.login(OPERATOR))
            async with client:
                events = await _wait_event(client, "paused")
                assert "disk nearly full" in events[0]["reason"]
                alarm = await _recording_alarm(client, active=True)
                assert "disk nearly full" in alarm["message"]
                answer = await client.get(
                    f"/api/v1/robots/{ROBOT}/history", params={"from": "0", "to": "1"}
                )
                assert answer.json()["recording"] is False
                assert "disk nearly full" in answer.json()["recording_paused_reason"]


async def _recording_alarm(client: httpx.AsyncClient, *, active: bool) -> dict[str, Any]:
    """The robot's ``recording_paused`` alarm once it is ``active`` (or not): it is raised on
    the web loop right after the event."""
    alarm_id = f"{ROBOT}:recording_paused"
    for _ in range(int(DEADLINE_S * 40)):
        answer = await client.get(f"/api/v1/alarms/{alarm_id}")
        assert answer.status_code == 200, answer.text
        if answer.json()["active"] is active:
            return dict(answer.json())
        await asyncio.sleep(0.1)
    raise AssertionError(f"{alarm_id} not active={active}")


async def _wait_event(client: httpx.AsyncClient, state: str) -> list[dict[str, Any]]:
    """The recording events of ``state`` in the event log, once there is one (the recorder
    checks the disk again every 5 s: a deadline well past that)."""
    for _ in range(int(DEADLINE_S * 40)):
        answer = await client.get("/api/v1/events", params={"kind": "recording"})
        assert answer.status_code == 200, answer.text
        items = [e for e in answer.json()["items"] if e["state"] == state]
        if items:
            return items
        await asyncio.sleep(0.1)
    raise AssertionError(f"no recording event {state!r}")


async def test_events_of_a_range_and_the_recording_status(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    robot = simulated()
    async with emulator(robot_host, robot) as target:
        settings = history_settings(target.tcp_port, robot_host, plc_host, tmp_path)
        async with running_service(settings) as hmi:
            before = await stream_frames(hmi, 50)
            robot.estop(time.time())
            after_stop: list[dict[str, Any]] = []
            for _ in range(int(DEADLINE_S * 10)):
                after_stop = await stream_frames(hmi, 10)
                if after_stop[-1]["frame"]["robot_state"] == 0:
                    break
            else:
                raise AssertionError("the emergency stop never showed")
            stopped_at = next(f["t"] for f in after_stop if f["frame"]["robot_state"] == 0)
            async with hmi.client() as client:
                await wait_recorded(client, before[0]["t"], after_stop[-1]["seq"])
                path = f"/api/v1/robots/{ROBOT}/history"
                span = {"from": before[0]["t"], "to": after_stop[-1]["t"] + 1}
                events = await client.get(
                    path + "/events", params={**span, "kind": ["robot_state", "flag"]}
                )
                few = await client.get(path + "/events", params={**span, "limit": 1})
                started = hmi.service.started_at
                none = await client.get(
                    path + "/events", params={"from": started - 100, "to": started - 50}
                )
                status = await client.get(path + "/status")
                # The first recorded frame that showed the stop (a stream opened and closed
                # in turn above may have missed it).
                around = await client.get(
                    path,
                    params={
                        "from": stopped_at - 0.5,
                        "to": stopped_at + 0.5,
                        "points": 5000,
                        "fields": "robot_state",
                    },
                )
    raw = around.json()
    assert raw["mode"] == "raw"
    first_stopped = next(
        t for t, state in zip(raw["t"], raw["series"][0]["values"], strict=True) if state == 0
    )
    assert events.status_code == 200, events.text
    body = events.json()
    assert body["truncated"] is False
    assert {e["kind"] for e in body["items"]} <= {"robot_state", "flag"}
    times = [e["time"] for e in body["items"]]
    assert times == sorted(times)
    stop = [e for e in body["items"] if e["kind"] == "robot_state" and e["to"] == 0]
    assert len(stop) == 1 and stop[0]["to_name"] == "EMERGENCY_STOP"
    # The marker sits on the frames' time axis: the first frame that showed the stop.
    assert stop[0]["time"] == pytest.approx(first_stopped, abs=1e-6)
    assert first_stopped <= stopped_at + 1e-6  # times recorded in whole microseconds
    assert len(few.json()["items"]) == 1 and few.json()["truncated"] is True
    assert none.json() == {"items": [], "truncated": False}
    state = status.json()
    assert state["robot"] == ROBOT and state["recording"] is True
    # (``first`` is a segment's name: whole microseconds)
    assert state["first"] <= before[0]["t"] + 1e-6
    assert after_stop[-1]["t"] <= state["last"]
    assert state["bytes"] > 0
    assert state["retention_days"] == 7.0


async def test_retention_by_age_deletes_the_oldest_while_recording_goes_on(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    """Recordings older than 3 s (segments of 1 s): the running service deletes the oldest
    segments first, the query no longer finds their frames, and recording goes on."""
    age_s = 3.0
    async with emulator(robot_host) as target:
        settings = history_settings(
            target.tcp_port,
            robot_host,
            plc_host,
            tmp_path,
            history_segment_s=1.0,
            history_retention_days=age_s / 86400,
        )
        async with running_service(settings) as hmi, hmi.client() as client:
            root = hmi.settings.history_path
            # Generous deadlines: a loaded machine closes segments late, never wrongly.
            for _ in range(int(DEADLINE_S * 30)):
                closed = segments.list_segments(root, ROBOT)
                if closed:
                    break
                await asyncio.sleep(0.1)
            else:
                raise AssertionError("no segment closed")
            oldest = closed[0]
            for _ in range(int(DEADLINE_S * 30)):
                if not oldest.path.exists():
                    break
                # The oldest first: no newer segment goes while the oldest is still there.
                newer_gone = [s.path.name for s in closed[1:] if not s.path.exists()]
                assert not newer_gone or not oldest.path.exists(), newer_gone
                await asyncio.sleep(0.1)
            else:
                raise AssertionError(f"{oldest.path.name} kept past {age_s} s")
            gone = await client.get(
                f"/api/v1/robots/{ROBOT}/history",
                params={"from": oldest.start_us / 1e6, "to": oldest.end_us / 1e6 + 1e-6},
            )
            # Recording goes on: frames received after the deletion reach the recording.
            seen = await stream_frames(hmi, 30)
            await wait_recorded(client, seen[0]["t"], seen[-1]["seq"])
            metrics = await hmi.metrics()
    assert not oldest.rollup_path.exists()
    assert gone.status_code == 200 and gone.json()["frames"] == 0
    deleted = re.search(
        r"^cobot_hmi_history_retention_deleted_segments_total (\S+)$", metrics, re.MULTILINE
    )
    assert deleted and float(deleted[1]) >= 1


async def test_a_recorder_that_falls_behind_drops_its_oldest_and_says_so(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    # A queue of 100 frames drained every 1.5 s at 100 frames/s: it overflows every time, by
    # construction (the recorder's queue, never the connection, gives way).
    async with emulator(robot_host) as target:
        settings = history_settings(
            target.tcp_port,
            robot_host,
            plc_host,
            tmp_path,
            history_queue_frames=100,
            history_flush_s=1.5,
        )
        async with running_service(settings) as hmi:
            async with hmi.client(await hmi.login(OPERATOR)) as client:
                events = await _wait_event(client, "overflow")
                frames = await stream_frames(hmi, 300)  # the stream does not miss a frame
            metrics = await hmi.metrics()
    assert events[0]["dropped"] > 0
    assert "fell behind" in events[0]["reason"]
    dropped = re.search(
        rf'cobot_hmi_history_frames_dropped_total{{robot="{ROBOT}"}} (\S+)', metrics
    )
    assert dropped and float(dropped[1]) >= events[0]["dropped"]
    seqs = [f["seq"] for f in frames]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))


async def test_every_robot_of_a_cell_is_recorded_apart(plc_host: str, tmp_path: Path) -> None:
    hosts = [_next_host(), _next_host()]
    robots = [SimulatedRobot(SimulationSettings(kinematic_refresh_ms=0.0, seed=s)) for s in (1, 2)]
    async with emulator(hosts[0], robots[0]) as left, emulator(hosts[1], robots[1]) as right:
        settings = cell_settings(
            [("left", hosts[0], left.tcp_port), ("right", hosts[1], right.tcp_port)],
            plc_host,
            tmp_path,
            history_segment_s=2.0,
            history_flush_s=0.2,
        )
        async with running_service(settings) as hmi, hmi.client() as client:
            recorded: dict[str, list[int]] = {}
            for _ in range(int(DEADLINE_S * 10)):
                for name in ("left", "right"):
                    now = time.time()
                    answer = await client.get(
                        f"/api/v1/robots/{name}/history",
                        params={"from": now - 60, "to": now + 60, "points": 5000,
                                "fields": "joint_position.0"},
                    )  # fmt: skip
                    assert answer.status_code == 200, answer.text
                    recorded[name] = answer.json()["seq"] or []
                if all(len(seqs) >= 300 for seqs in recorded.values()):
                    break
                await asyncio.sleep(0.2)
            else:
                raise AssertionError(f"not recorded: {[len(v) for v in recorded.values()]}")
            values = {}
            for name in ("left", "right"):
                answer = await client.get(
                    f"/api/v1/robots/{name}/export",
                    params={"from": 0, "to": 4e9, "format": "parquet"},
                )
                values[name] = pq.read_table(pa.BufferReader(answer.content))
    for name in ("left", "right"):
        seqs = values[name].column("seq").to_pylist()
        assert seqs == list(range(1, len(seqs) + 1)), name  # each robot's every frame
        assert (tmp_path / "history" / name).is_dir()
    # Two robots, two recordings: each robot's own values (their simulations' seeds differ).
    left_rows = {bytes(row) for row in raw_from_columns(values["left"])}
    right_rows = {bytes(row) for row in raw_from_columns(values["right"])}
    assert len(left_rows & right_rows) < len(left_rows) / 2
