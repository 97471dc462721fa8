"""Cycle timing against the real emulator and service (issue 23): the emulator's demo program
marks each cycle start on bit output register 63, the service's cycle trigger is that
register's rising edge, and the cycles the API answers are the ones computed from the
recorder's own Parquet of the same range (every frame, its receive time to the microsecond).
The API's statistics, its CSV, its time range and its answer for a robot without a trigger."""

from __future__ import annotations

import csv
import io
import itertools
import time
from datetime import datetime
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from cobot_hmi.emulator.robot import RobotSettings as SimulationSettings
from cobot_hmi.emulator.robot import SimulatedRobot
from cobot_hmi.generated.frames import RobotState
from cobot_hmi.history.schema import ELEMENT_BY_EXPORT_NAME, time_seconds
from cobot_hmi.service.cycles.meter import MAX_GAP_S
from emulator_harness import FAST_TIMINGS, running_emulator
from service_support import (
    DEADLINE_S,
    Running,
    emulator,
    eventually_async,
    running_service,
    service_settings,
)

pytestmark = pytest.mark.timeout(240)

ROBOT = "robot"
MARKER = 63
TRIGGER = f"bit_output_registers.{MARKER}:rising"
CYCLES = 3
"""Cycles measured before comparing (~8 s each)."""
TIME_TOLERANCE_S = 2e-6
"""The recording keeps receive times in whole microseconds."""


def marked_robot() -> SimulatedRobot:
    return SimulatedRobot(SimulationSettings(timings=FAST_TIMINGS, cycle_marker_register=MARKER))


async def cycles(hmi: Running, **params: Any) -> dict[str, Any]:
    async with hmi.client() as client:
        answer = await client.get(f"/api/v1/robots/{ROBOT}/cycles", params=params)
    assert answer.status_code == 200, answer.text
    body: dict[str, Any] = answer.json()
    return body


async def export(hmi: Running, from_s: float, to_s: float) -> pa.Table:
    async with hmi.client() as client:
        answer = await client.get(
            f"/api/v1/robots/{ROBOT}/export",
            params={"from": from_s, "to": to_s, "format": "parquet"},
        )
    assert answer.status_code == 200, answer.text
    return pq.read_table(pa.BufferReader(answer.content))


def _marker_frames(table: pa.Table) -> list[tuple[float, bool]]:
    times = time_seconds(table)
    (name,) = (
        n for n, e in ELEMENT_BY_EXPORT_NAME.items() if e.name == f"bit_output_registers.{MARKER}"
    )
    return list(zip((float(t) for t in times), table.column(name).to_pylist(), strict=True))


def starts_in(table: pa.Table) -> list[float]:
    """The receive times of the frames where the marker rose (the first frame only says where
    the level is)."""
    frames = _marker_frames(table)
    return [t for (_, was), (t, now) in itertools.pairwise(frames) if now and not was]


def cycles_in(table: pa.Table) -> list[tuple[float, float, bool]]:
    """The cycles of the recorded frames, from one rise to the next, by brute force, each with
    whether frames further apart than the meter's MAX_GAP_S (a robot silent that long, as a
    loaded machine's emulator can be) interrupted it; the frame after such a silence only says
    where the level is."""
    found: list[tuple[float, float, bool]] = []
    start: float | None = None
    silent = False
    for (was_s, was), (t, now) in itertools.pairwise(_marker_frames(table)):
        if t - was_s > MAX_GAP_S:
            silent = True
            continue
        if now and not was:
            if start is not None:
                found.append((start, t, silent))
            start, silent = t, False
    return found


async def test_cycles_equal_those_computed_from_the_recorded_frames(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    async with emulator(robot_host, marked_robot()) as target:
        settings = service_settings(
            robot_host,
            target.tcp_port,
            plc_host,
            tmp_path,
            cycle_trigger=TRIGGER,
            history_segment_s=2.0,
            history_flush_s=0.2,
        )
        async with running_service(settings) as hmi:

            async def measured() -> bool:
                return len((await cycles(hmi))["cycles"]) >= CYCLES

            await eventually_async(measured, timeout_s=120)
            body = await cycles(hmi, last=2)
            measured_cycles = body["cycles"]
            first, last = measured_cycles[0], measured_cycles[-1]

            # The recorder flushes every 0.2 s: wait until the last cycle's end is in it.
            async def recorded() -> bool:
                table = await export(hmi, last["end"] - 1.0, last["end"] + 1.0)
                return any(abs(t - last["end"]) < TIME_TOLERANCE_S for t in starts_in(table))

            await eventually_async(recorded, timeout_s=DEADLINE_S)
            table = await export(hmi, first["start"] - 1.0, last["end"] + 0.001)
            ranged = await cycles(hmi, **{"from": first["start"] + 0.001})
            iso = datetime.fromtimestamp(first["start"] + 0.001).astimezone().isoformat()
            ranged_iso = await cycles(hmi, **{"from": iso})
            async with hmi.client() as client:
                csv_answer = await client.get(
                    f"/api/v1/robots/{ROBOT}/cycles", params={"format": "csv"}
                )
                # Each cycle is an event too, at its start: the plots' markers.
                marked = await client.get(
                    f"/api/v1/robots/{ROBOT}/history/events",
                    params={"from": first["start"] - 0.5, "to": last["end"]},
                )
    cycle_events = [e for e in marked.json()["items"] if e["kind"] == "cycle"]
    assert [(e["time"], e["end"]) for e in cycle_events] == [
        (pytest.approx(c["start"], abs=1e-5), pytest.approx(c["end"], abs=1e-5))
        for c in measured_cycles
    ]
    said = f"Cycle of {measured_cycles[-1]['duration_s']:.2f} s"
    if measured_cycles[-1]["interrupted"]:  # a loaded machine's silence (see cycles_in)
        said += f", interrupted: {measured_cycles[-1]['interruption']}"
    assert cycle_events[-1]["text"] == said
    expected = cycles_in(table)
    assert len(expected) == len(measured_cycles)
    for (start, end, silent), cycle in zip(expected, measured_cycles, strict=True):
        assert cycle["interrupted"] is silent
        assert cycle["start"] == pytest.approx(start, abs=TIME_TOLERANCE_S)
        assert cycle["end"] == pytest.approx(end, abs=TIME_TOLERANCE_S)
        assert cycle["duration_s"] == pytest.approx(end - start, abs=2 * TIME_TOLERANCE_S)
    # The demo program's cycle (~8 s), about the same each time (a busy machine delays frames).
    durations = [c["duration_s"] for c in measured_cycles if not c["interrupted"]]
    assert min(durations) > 1.0 and max(durations) - min(durations) < 1.0
    assert body["trigger"] == {
        "text": TRIGGER,
        "label": f"rising edge of Register out {MARKER}",
    }
    stats = body["statistics"]
    assert stats["count"] == len(durations)
    assert stats["last_s"] == pytest.approx(durations[-1])
    assert stats["window"] == min(2, len(durations))
    assert stats["mean_s"] == pytest.approx(sum(durations[-2:]) / len(durations[-2:]))
    assert stats["min_s"] == pytest.approx(min(durations[-2:]))
    assert stats["max_s"] == pytest.approx(max(durations[-2:]))
    assert body["in_progress_since"] == pytest.approx(last["end"])
    # A range: cycles that started in it.
    assert ranged["cycles"][0]["id"] == measured_cycles[1]["id"]
    assert ranged_iso["cycles"] == ranged["cycles"]
    # CSV: a header and one row per cycle, ISO 8601 times.
    assert csv_answer.status_code == 200
    assert csv_answer.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(csv_answer.text)))
    assert int(csv_answer.headers["x-total-count"]) == len(rows) >= CYCLES
    assert [float(r["duration_s"]) for r in rows[: len(measured_cycles)]] == pytest.approx(
        [c["duration_s"] for c in measured_cycles]
    )
    assert datetime.fromisoformat(rows[0]["start"]).timestamp() == pytest.approx(
        measured_cycles[0]["start"], abs=1e-5
    )


async def test_a_robot_without_a_trigger_answers_no_cycles_and_bad_input_is_refused(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    async with emulator(robot_host, marked_robot()) as target:
        settings = service_settings(robot_host, target.tcp_port, plc_host, tmp_path)
        async with running_service(settings) as hmi:
            body = await cycles(hmi)
            async with hmi.client() as client:
                bad_time = await client.get(
                    f"/api/v1/robots/{ROBOT}/cycles", params={"from": "yesterday"}
                )
                bad_last = await client.get(f"/api/v1/robots/{ROBOT}/cycles", params={"last": 0})
                unknown = await client.get("/api/v1/robots/nobody/cycles")
    assert body["trigger"] is None and body["cycles"] == []
    assert body["statistics"] == {
        "count": 0,
        "interrupted": 0,
        "include_interrupted": False,
        "last_s": None,
        "window": 0,
        "mean_s": None,
        "min_s": None,
        "max_s": None,
    }
    assert bad_time.status_code == 422 and bad_time.json()["detail"]["field"] == "from"
    assert "ISO 8601" in bad_time.json()["detail"]["reason"]
    assert bad_last.status_code == 422
    assert unknown.status_code == 404


async def test_a_cycle_across_an_emergency_stop_is_interrupted_and_left_out(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    """Issue 38: the demo program's cycle in progress when the robot is e-stopped (reset, the
    program started again) is kept, marked interrupted with what did it, and left out of the
    statistics unless include_interrupted=true; the trigger is named by its label."""
    settings = SimulationSettings(timings=FAST_TIMINGS, cycle_marker_register=MARKER)
    async with running_emulator(robot_host, plc_host, settings) as emu:
        hmi_settings = service_settings(
            robot_host, emu.target.tcp_port, plc_host, tmp_path, cycle_trigger=TRIGGER
        )
        async with running_service(hmi_settings) as hmi:
            robot = hmi.service.default_robot

            async def state_is(*states: RobotState) -> bool:
                latest = robot.frames.latest
                return latest is not None and latest.frame.robot_state in states

            async def in_progress() -> bool:
                return (await cycles(hmi))["in_progress_since"] is not None

            await eventually_async(in_progress, timeout_s=60)
            await emu.post("/estop")
            await eventually_async(lambda: state_is(RobotState.EMERGENCY_STOP))
            await emu.post("/reset")
            await eventually_async(lambda: state_is(RobotState.STANDALONE_STANDBY))
            await emu.post("/program", {"running": True})

            async def whole_after_interrupted() -> bool:
                rows = (await cycles(hmi))["cycles"]
                return any(c["interrupted"] for c in rows) and not rows[-1]["interrupted"]

            await eventually_async(whole_after_interrupted, timeout_s=120)
            body = await cycles(hmi)
            included = await cycles(hmi, include_interrupted="true")
            async with hmi.client() as client:
                csv_answer = await client.get(
                    f"/api/v1/robots/{ROBOT}/cycles", params={"format": "csv"}
                )
                marked = await client.get(
                    f"/api/v1/robots/{ROBOT}/history/events",
                    params={"from": body["cycles"][0]["start"] - 0.5, "to": time.time()},
                )
    rows = body["cycles"]
    texts = [e["text"] for e in marked.json()["items"] if e["kind"] == "cycle"]
    assert any(t.endswith("s, interrupted: Emergency stop") for t in texts), texts
    interrupted = [c for c in rows if c["interrupted"]]
    whole = [c for c in rows if not c["interrupted"]]
    # The e-stop's cycle, and on a loaded machine perhaps a cycle across a silence of the
    # frames (the meter's MAX_GAP_S: "no frames for 1.2 s (link lost)"), never anything else.
    (stopped,) = [c for c in interrupted if c["interruption"] == "Emergency stop"]
    silences = [c for c in interrupted if c is not stopped]
    assert all(c["interruption"].endswith("(link lost)") for c in silences), silences
    assert all(c["interruption"] is None for c in whole)
    long_one = stopped["duration_s"]
    assert long_one > max(c["duration_s"] for c in whole)
    stats = body["statistics"]
    assert stats["count"] == len(whole) and stats["interrupted"] == len(interrupted)
    assert stats["include_interrupted"] is False
    assert stats["max_s"] == pytest.approx(max(c["duration_s"] for c in whole))
    assert stats["last_s"] == pytest.approx(whole[-1]["duration_s"])
    every = included["statistics"]
    assert every["count"] == len(rows) and every["include_interrupted"] is True
    assert every["max_s"] == pytest.approx(max(c["duration_s"] for c in interrupted))
    assert body["trigger"]["label"] == f"rising edge of Register out {MARKER}"
    csv_rows = list(csv.DictReader(io.StringIO(csv_answer.text)))
    assert [r["interrupted"] for r in csv_rows] == [str(c["interrupted"]) for c in rows]
    assert int(csv_answer.headers["x-total-count"]) == len(rows)
