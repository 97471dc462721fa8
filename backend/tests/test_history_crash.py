"""``kill -9`` of ``cobot-hmi serve`` while it records: every closed segment stays readable and
complete, every frame the service had reported recorded is still there (read by ``cobot-hmi
export`` without a service), and a restart closes the crash's journal and records on in a new
segment. Retention runs while the service records."""

from __future__ import annotations

import asyncio
import signal
import sys
import time
from pathlib import Path

import httpx
import pyarrow.parquet as pq
import pytest

from cobot_hmi.emulator.robot import RobotSettings as SimulationSettings
from cobot_hmi.emulator.robot import SimulatedRobot
from cobot_hmi.history import segments
from cobot_hmi.history.cells import read_cells_file
from conftest import free_tcp_port
from process_support import cli_process, wait_ready
from service_support import DEADLINE_S, emulator, eventually, running_service, service_settings

pytestmark = pytest.mark.timeout(240)

ROBOT = "robot"


async def recorded_seq(client: httpx.AsyncClient) -> int:
    """The newest frame counter the service answers from its recording (0: none yet)."""
    now = time.time()
    answer = await client.get(
        f"/api/v1/robots/{ROBOT}/history",
        params={"from": now - 600, "to": now + 600, "points": 5000, "fields": "robot_state"},
    )
    assert answer.status_code == 200, answer.text
    body = answer.json()
    if body["mode"] == "raw":
        return int(body["seq"][-1]) if body["seq"] else 0
    return int(body["frames"])  # (counters start at 1 and rise by one per frame)


def serve_args(robot_host: str, tcp_port: int, plc_host: str, port: int, state: Path) -> list[str]:
    return [
        "serve",
        "--robot",
        robot_host,
        "--robot-tcp-port",
        str(tcp_port),
        "--local-host",
        plc_host,
        "--host",
        plc_host,
        "--port",
        str(port),
        "--state-dir",
        str(state),
        "--timeout-multiplier",
        "5",
        "--history-segment-s",
        "1",
        "--history-flush-s",
        "0.5",
    ]


async def test_kill_9_keeps_what_was_recorded(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    port = free_tcp_port(plc_host)
    base_url = f"http://{plc_host}:{port}"
    robot = SimulatedRobot(SimulationSettings(kinematic_refresh_ms=0.0))
    async with emulator(robot_host, robot) as target:
        args = serve_args(robot_host, target.tcp_port, plc_host, port, tmp_path)
        async with cli_process(*args) as service:
            await wait_ready(base_url, service)
            async with httpx.AsyncClient(base_url=base_url, timeout=DEADLINE_S) as client:
                # Record until at least three segments (a second each) are closed, then note
                # the newest frame the service says it has recorded, and kill it at once.
                await eventually(
                    lambda: len(segments.list_segments(tmp_path / "history", ROBOT)) >= 3
                )
                reported = await recorded_seq(client)
                service.send_signal(signal.SIGKILL)
            await service.wait()
            assert service.returncode == -signal.SIGKILL
        closed = segments.list_segments(tmp_path / "history", ROBOT)
        journals = segments.list_journals(tmp_path / "history", ROBOT)
        # Every closed segment is whole Parquet; the journal of the open one is readable.
        counters: list[int] = []
        for segment in closed:
            counters += pq.read_table(segment.path).column("seq").to_pylist()
            cells = read_cells_file(segment.rollup_path, ["cell"])
            assert cells is not None and cells.num_rows >= 1
        for _, journal in journals:
            counters += segments.read_journal(journal).column("seq").to_pylist()
        assert counters == list(range(1, len(counters) + 1))
        assert len(counters) >= reported > 0
        # The command line reads the crashed recording without a service.
        export_path = tmp_path / "after-crash.parquet"
        async with cli_process(
            "export",
            "--state-dir",
            str(tmp_path),
            "--from",
            "0",
            "--to",
            "4000000000",
            "--format",
            "parquet",
            "-o",
            str(export_path),
        ) as exporter:
            output, _ = await exporter.communicate()
        assert exporter.returncode == 0, output
        assert pq.read_table(export_path).column("seq").to_pylist() == counters
        # A restart closes the crash's journal and records on in a new segment.
        crashed_segments = {s.path for s in closed}
        async with cli_process(*args) as service:
            await wait_ready(base_url, service)
            await eventually(
                lambda: len(segments.list_segments(tmp_path / "history", ROBOT)) >= len(closed) + 2
            )
            service.send_signal(signal.SIGTERM)
            await asyncio.wait_for(service.wait(), DEADLINE_S * 3)
    after = segments.list_segments(tmp_path / "history", ROBOT)
    assert crashed_segments <= {s.path for s in after}
    assert segments.list_journals(tmp_path / "history", ROBOT) == []  # a clean stop closes it
    new = [s for s in after if s.path not in crashed_segments]
    recovered_and_new = [pq.read_table(s.path).column("seq").to_pylist() for s in new]
    flat = [seq for part in recovered_and_new for seq in part]
    # The crash's journal (counters going on from the last closed segment), then the new run
    # from 1 again: a frame counter per run of the service.
    restart = flat.index(1)
    assert flat[:restart] == counters[len(counters) - restart :]
    assert flat[restart:] == list(range(1, len(flat) - restart + 1))
    assert sys.platform.startswith("linux")


async def test_retention_runs_while_recording(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    # A size bound of a few segments (each about 100 kB here, mostly Parquet footers): the
    # recorder deletes the oldest as new ones close.
    async with emulator(robot_host) as target:
        settings = service_settings(
            robot_host,
            target.tcp_port,
            plc_host,
            tmp_path,
            history_segment_s=0.5,
            history_flush_s=0.2,
            history_retention_bytes=400_000,
        )
        async with running_service(settings) as hmi:
            recorder = hmi.service.recorder
            assert recorder is not None
            await eventually(
                lambda: (
                    recorder.retention_deleted_segments >= 2
                    and bool(segments.list_segments(settings.history_path, ROBOT))
                )
            )
            deleted_up_to = min(
                s.start_us for s in segments.list_segments(settings.history_path, ROBOT)
            )
            metrics = await hmi.metrics()
    assert "cobot_hmi_history_retention_deleted_segments_total" in metrics
    # What is left once the service stopped (retention went on deleting while it ran, so the
    # segments listed above may be gone) is the newest: the first counter kept is not 1 (the
    # oldest went first), and what is kept has no hole.
    kept = segments.list_segments(settings.history_path, ROBOT)
    assert kept and min(s.start_us for s in kept) >= deleted_up_to
    tables = [pq.read_table(s.path).column("seq").to_pylist() for s in kept]
    flat = [seq for part in tables for seq in part]
    assert flat[0] > 1
    assert flat == list(range(flat[0], flat[0] + len(flat)))
    assert deleted_up_to > 0
