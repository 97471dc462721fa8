"""Issue 38: a CSV export of a range the recording has nothing of says so in the file, as the
plot says it ("nothing recorded from … to …"); one with frames has no such line. Against the
real emulator and service on loopback, the recorder writing its files."""

from __future__ import annotations

import csv
import io
from datetime import UTC, datetime
from pathlib import Path

import httpx
import pytest

from cobot_hmi.emulator.robot import RobotSettings as SimulationSettings
from cobot_hmi.emulator.robot import SimulatedRobot
from emulator_harness import FAST_TIMINGS
from service_support import emulator, eventually_async, running_service, service_settings

pytestmark = pytest.mark.timeout(120)

ROBOT = "robot"


async def export_csv(client: httpx.AsyncClient, from_s: float, to_s: float) -> str:
    answer = await client.get(
        f"/api/v1/robots/{ROBOT}/export",
        params={"from": from_s, "to": to_s, "format": "csv", "fields": "robot_state"},
    )
    assert answer.status_code == 200, answer.text
    return answer.text


async def test_a_csv_export_of_nothing_recorded_says_so(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    robot = SimulatedRobot(SimulationSettings(timings=FAST_TIMINGS))
    async with emulator(robot_host, robot) as target:
        settings = service_settings(
            robot_host,
            target.tcp_port,
            plc_host,
            tmp_path,
            history_segment_s=2.0,
            history_flush_s=0.2,
        )
        async with running_service(settings) as hmi, hmi.client() as client:
            latest = hmi.service.default_robot.frames.latest
            started_s = (
                latest.received_at_s if latest is not None else datetime.now(UTC).timestamp()
            )
            before = await export_csv(client, started_s - 3600, started_s - 3480)

            async def recorded() -> bool:
                now_s = datetime.now(UTC).timestamp()
                text = await export_csv(client, now_s - 30, now_s)
                return len(text.splitlines()) > 2

            await eventually_async(recorded, timeout_s=60)
            now_s = datetime.now(UTC).timestamp()
            during = await export_csv(client, now_s - 30, now_s)
    lines = before.splitlines()
    assert len(lines) == 2 and lines[0].startswith('"time"')
    when = datetime.fromtimestamp(started_s - 3600, UTC).strftime("%Y-%m-%dT%H:%M:%S")
    assert lines[1].startswith(f"# nothing recorded from {when}")
    assert " to " in lines[1] and lines[1].endswith("Z")
    rows = list(csv.reader(io.StringIO(during)))
    assert len(rows) > 2 and not any(r and r[0].startswith("#") for r in rows)


async def test_an_export_reaching_the_present_holds_every_frame_received(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    """The recorder writes once per flush period (here its longest, 1.5 s); an export whose
    range reaches the present has the frames it still held written first, so the file ends
    with the newest frame the service had received when it was asked (the page's view ends
    there too), not up to 1.5 s before it. Three exports in a row: each holds the newest."""
    robot = SimulatedRobot(SimulationSettings(timings=FAST_TIMINGS))
    async with emulator(robot_host, robot) as target:
        settings = service_settings(
            robot_host, target.tcp_port, plc_host, tmp_path, history_flush_s=1.5
        )
        async with running_service(settings) as hmi, hmi.client() as client:
            frames = hmi.service.default_robot.frames

            async def recorded() -> bool:
                now_s = datetime.now(UTC).timestamp()
                return len((await export_csv(client, now_s - 30, now_s + 5)).splitlines()) > 2

            await eventually_async(recorded, timeout_s=60)
            for _ in range(3):
                latest = frames.latest
                assert latest is not None
                newest_before_s = latest.received_at_s
                now_s = datetime.now(UTC).timestamp()
                text = await export_csv(client, now_s - 30, now_s + 5)
                last = next(csv.reader(io.StringIO(text.splitlines()[-1])))
                last_s = datetime.fromisoformat(last[0]).timestamp()
                # RPI 10 ms: the newest frame before the request is in the file (a frame's
                # time is written to the microsecond).
                assert last_s >= newest_before_s - 1e-3, (last_s, newest_before_s)
