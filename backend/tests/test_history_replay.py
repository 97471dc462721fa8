"""Replay: a recording played back by the emulator (``ReplayRobot``, and ``cobot-hmi emulator
--replay`` as its own process) reaches the service over the real protocol with the recording's
values, in the recording's order; the service records the replay, so the two recordings compare
frame by frame."""

from __future__ import annotations

import asyncio
import contextlib
import os
import sys
from collections.abc import AsyncIterator
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from cobot_hmi.codec import encode_frame
from cobot_hmi.emulator.replay_robot import ReplayRobot
from cobot_hmi.history import export
from cobot_hmi.history.recording import Recording, read_recording
from cobot_hmi.history.schema import raw_from_columns, select_elements
from conftest import free_tcp_port
from service_support import DEADLINE_S, Running, emulator, running_service, service_settings
from test_history_storage import Item, synthetic_items, write_recording

pytestmark = pytest.mark.timeout(180)

FRAMES = 60
SPEED = 0.1
"""Each 10 ms frame plays for 100 ms: ten RPIs of the service's connection."""


def recording_file(tmp_path: Path, fmt: str) -> tuple[Path, list[Item]]:
    """A recording of ``FRAMES`` distinct frames exported as ``fmt``."""
    items = synthetic_items(FRAMES, seed=7)
    source = tmp_path / "source"
    write_recording(source, "incident", items, 25)
    elements = select_elements(None)
    tables = export.tables(
        source, "incident", elements, from_s=items[0][1], to_s=items[-1][1] + 1, fmt=fmt
    )
    path = tmp_path / f"incident.{fmt}"
    path.write_bytes(b"".join(export.export(tables, "incident", elements, fmt)))
    return path, items


async def replayed_frames(hmi: Running, last: bytes) -> list[bytes]:
    """The service's own recording of what it received, once the last recorded frame arrived:
    each distinct frame once, in order."""
    robot = hmi.service.default_robot
    for _ in range(int(DEADLINE_S * 20)):
        latest = robot.hub.latest
        if latest is not None and encode_frame(latest[2]) == last:
            break
        await asyncio.sleep(0.05)
    else:
        raise AssertionError("the replay's last frame never arrived")
    await asyncio.sleep(0.5)  # a few flushes of the recorder (it flushes every 0.2 s here)
    root = hmi.settings.history_path
    elements = select_elements(None)
    tables = list(export.tables(root, robot.name, elements, from_s=0, to_s=4e9, fmt="parquet"))
    raw = raw_from_columns(pa.concat_tables(tables))
    distinct: list[bytes] = []
    for row in raw:
        data = row.tobytes()
        if not distinct or distinct[-1] != data:
            distinct.append(data)
    return distinct


def check_replayed(distinct: list[bytes], items: list[Item]) -> None:
    expected = [encode_frame(item[2]) for item in items]
    # Every frame the service received is a recorded frame, in the recording's order ...
    positions = [expected.index(data) for data in distinct]
    assert positions == sorted(positions)
    assert len(set(positions)) == len(positions)
    # ... the replay ran to its end, and (each held for ten RPIs) hardly any was skipped.
    assert positions[-1] == FRAMES - 1
    assert len(positions) >= 0.9 * FRAMES, positions


async def test_replay_robot_reproduces_a_parquet_recording(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    path, items = recording_file(tmp_path, "parquet")
    recording = read_recording(path)
    assert len(recording) == FRAMES
    replay = ReplayRobot(recording, speed=SPEED)
    async with emulator(robot_host, replay) as target:
        settings = service_settings(
            robot_host, target.tcp_port, plc_host, tmp_path / "state", history_flush_s=0.2
        )
        async with running_service(settings) as hmi:
            distinct = await replayed_frames(hmi, encode_frame(items[-1][2]))
    check_replayed(distinct, items)


def test_replay_robot_timing() -> None:
    times = np.array([100.0, 100.01, 100.02, 100.05])
    raw = np.arange(4 * 284, dtype=np.uint32).astype(np.uint8).reshape(4, 284)
    robot = ReplayRobot(Recording(times, raw), speed=2.0, start_s=50.0)
    assert [robot.index_at(50.0 + dt) for dt in (0, 0.004, 0.005, 0.012, 0.024, 0.025, 9)] == [
        0,
        0,
        1,
        2,
        2,
        3,
        3,
    ]
    looping = ReplayRobot(Recording(times, raw), loop=True, start_s=0.0)
    # One loop lasts the recording plus its typical interval (0.06 s here).
    assert looping.index_at(0.065) == 0
    assert looping.index_at(0.071) == 1
    assert looping.loops == 1
    with pytest.raises(ValueError, match="speed"):
        ReplayRobot(Recording(times, raw), speed=0)


@contextlib.asynccontextmanager
async def replay_process(*args: str) -> AsyncIterator[asyncio.subprocess.Process]:
    process = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "cobot_hmi.cli",
        "emulator",
        *args,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.STDOUT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        yield process
    finally:
        if process.returncode is None:
            process.kill()
        await process.communicate()


async def test_emulator_replay_verb_plays_an_mcap_export(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    path, items = recording_file(tmp_path, "mcap")
    tcp_port = free_tcp_port(robot_host)
    async with replay_process(
        "--host",
        robot_host,
        "--tcp-port",
        str(tcp_port),
        "--no-discovery",
        "--replay",
        str(path),
        "--speed",
        str(SPEED),
    ) as process:
        assert process.stdout is not None
        ready = await asyncio.wait_for(process.stdout.readline(), DEADLINE_S * 3)
        assert b"EtherNet/IP target on" in ready, ready
        settings = service_settings(
            robot_host, tcp_port, plc_host, tmp_path / "state", history_flush_s=0.2
        )
        async with running_service(settings) as hmi:
            distinct = await replayed_frames(hmi, encode_frame(items[-1][2]))
    check_replayed(distinct, items)


async def test_emulator_replay_verb_refuses_a_file_that_is_no_recording(tmp_path: Path) -> None:
    bad = tmp_path / "notes.txt"
    bad.write_text("time,seq\n")
    async with replay_process("--host", "127.0.0.1", "--replay", str(bad)) as process:
        output, _ = await asyncio.wait_for(process.communicate(), DEADLINE_S * 3)
    assert process.returncode == 2
    assert b"neither Parquet nor MCAP" in output


def test_parquet_export_of_some_fields_replays_the_rest_as_zero(tmp_path: Path) -> None:
    items = synthetic_items(5)
    write_recording(tmp_path, "r", items, 5)
    elements = select_elements(["joint_position"])
    tables = export.tables(tmp_path, "r", elements, from_s=0, to_s=4e9, fmt="parquet")
    path = tmp_path / "some.parquet"
    path.write_bytes(b"".join(export.export(tables, "r", elements, "parquet")))
    assert pq.read_schema(path).names[3:] == [f"joint_position.{i}" for i in range(6)]
    recording = read_recording(path)
    for row, (_, _, frame, _) in zip(recording.raw, items, strict=True):
        decoded = ReplayRobot(Recording(np.array([0.0]), row[None, :]))
        replayed = decoded.produce_frame(0.0)
        assert replayed.joint_position == frame.joint_position
        assert replayed.robot_state == 0
