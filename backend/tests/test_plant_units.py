"""The plant's history (hourly Parquet segments, read back by an independent reader, DuckDB) and
its web app's own checks (login, the viewer gate, the Host check), with a plain HTTP client on
a real socket that does none of the server's checking for it."""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
from collections.abc import AsyncIterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import duckdb
import httpx
import pyarrow.parquet as pq
import pytest
import uvicorn

from cobot_hmi.plant import recorder as recorder_module
from cobot_hmi.plant.app import create_plant_app
from cobot_hmi.plant.host import Sample
from cobot_hmi.plant.plant_settings import PlantSettings
from cobot_hmi.plant.recorder import PLANT_SEGMENT, MetricKey, PlantRecorder
from cobot_hmi.plant.runtime import PlantRuntime
from cobot_hmi.service.access.users import Role, UsersFile
from conftest import free_tcp_port
from waiting import eventually

HOUR_MS = 3_600_000


def _sample(
    time_ms: int, value: object, metric: str = "robot_state", historical: bool = False
) -> Sample:
    return Sample(time_ms, "plant", "cell-1", "m1013", metric, value, historical)  # type: ignore[arg-type]


def test_values_go_into_the_hour_they_happened_and_read_back(tmp_path: Path) -> None:
    recorder = PlantRecorder(tmp_path)
    now_ms = int(time.time() * 1000)
    start_ms = now_ms - now_ms % HOUR_MS - 2 * HOUR_MS  # two hours ago, on the hour
    recorder.add([_sample(start_ms + 1000, 13), _sample(start_ms + HOUR_MS + 5, 14)])
    recorder.add([_sample(start_ms + 2000, "late", historical=True)])  # replayed, older hour
    recorder.add([_sample(start_ms + 3000, 2.5, metric="joint/J1")])
    assert recorder.flush() == 4
    hours = sorted(p.name for p in tmp_path.iterdir())
    first = datetime.fromtimestamp(start_ms / 1000, UTC)
    assert hours == [
        first.strftime("%Y-%m-%dT%H"),
        (first + timedelta(hours=1)).strftime("%Y-%m-%dT%H"),
    ]
    key = MetricKey("plant", "cell-1", "m1013", "robot_state")
    points = recorder.trend(key, start_ms, start_ms + 2 * HOUR_MS)
    assert [(p.time_ms - start_ms, p.value, p.text, p.historical) for p in points] == [
        (1000, 13.0, None, False),
        (2000, None, "late", True),
        (HOUR_MS + 5, 14.0, None, False),
    ]
    # An independent reader sees the same rows, and every file says its format's version.
    files = sorted(str(p) for p in tmp_path.glob("*/*.parquet"))
    relation = duckdb.sql(
        f"SELECT count(*) FROM read_parquet({files!r}) WHERE metric = 'robot_state'"
    )
    assert relation is not None
    rows = relation.fetchall()
    assert rows == [(3,)]
    for path in files:
        version = pq.read_schema(path).metadata[b"cobot_hmi.format_version"]
        assert version == str(PLANT_SEGMENT.version).encode()


def test_a_finished_hour_is_compacted_and_a_newer_format_left_out(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    recorder = PlantRecorder(tmp_path)
    old_ms = int(time.time() * 1000) - 5 * HOUR_MS
    for index in range(3):  # three flushes: three parts
        recorder.add([_sample(old_ms + index, index)])
        recorder.flush()
    [folder] = list(tmp_path.iterdir())
    assert sorted(p.name for p in folder.iterdir()) == ["segment.parquet"]
    key = MetricKey("plant", "cell-1", "m1013", "robot_state")
    assert [p.value for p in recorder.trend(key, old_ms - 1, old_ms + 10)] == [0.0, 1.0, 2.0]
    # A file a newer cobot-hmi wrote is not read (nor rewritten).
    newer = recorder_module.SCHEMA.with_metadata({b"cobot_hmi.format_version": b"99"})
    table = pq.read_table(folder / "segment.parquet").replace_schema_metadata(newer.metadata)
    pq.write_table(table, folder / "part-newer.parquet")
    assert len(recorder.trend(key, old_ms - 1, old_ms + 10)) == 3
    # ... nor removed nor overwritten by the next compaction, which takes the part it can read.
    recorder.add([_sample(old_ms + 5, 5)])
    recorder.flush()
    assert sorted(p.name for p in folder.iterdir()) == ["part-newer.parquet", "segment.parquet"]
    assert [p.value for p in recorder.trend(key, old_ms - 1, old_ms + 10)] == [0.0, 1.0, 2.0, 5.0]
    # A part the segment has absorbed but that is still on disk (a compaction between its
    # write and its removals) is not counted twice.
    absorbed = folder / "segment.parquet"
    survivor = folder / "part-0-0.parquet"
    survivor.write_bytes(absorbed.read_bytes())
    names = json.loads(pq.read_schema(absorbed).metadata[b"cobot_hmi.absorbed_parts"])
    table = pq.read_table(absorbed)
    metadata = {
        **table.schema.metadata,
        b"cobot_hmi.absorbed_parts": json.dumps([*names, survivor.name]).encode(),
    }
    pq.write_table(table.replace_schema_metadata(metadata), absorbed)
    assert len(recorder.trend(key, old_ms - 1, old_ms + 10)) == 4
    recorder.add([_sample(old_ms + 6, 6)])
    recorder.flush()  # the next compaction removes it rather than taking its rows again
    assert not survivor.exists()
    assert [p.value for p in recorder.trend(key, old_ms - 1, old_ms + 10)] == [
        0.0,
        1.0,
        2.0,
        5.0,
        6.0,
    ]


@contextlib.asynccontextmanager
async def _plant_app(settings: PlantSettings) -> AsyncIterator[str]:
    runtime = PlantRuntime(settings)
    config = uvicorn.Config(
        create_plant_app(runtime),
        host=settings.web.host,
        port=settings.web.port,
        log_level="warning",
        lifespan="on",
    )
    server = uvicorn.Server(config)
    task = asyncio.create_task(server.serve())
    try:
        await eventually(lambda: server.started or task.done())
        assert not task.done()
        yield f"http://{settings.web.host}:{settings.web.port}"
    finally:
        server.should_exit = True
        await task


async def test_the_plant_api_is_the_services_login_and_checks(
    plc_host: str, tmp_path: Path
) -> None:
    settings = PlantSettings.from_keys(
        host=plc_host,
        port=free_tcp_port(plc_host),
        state_dir=tmp_path,
        mqtt_urls=[f"mqtt://{plc_host}:{free_tcp_port(plc_host)}"],  # no broker: it retries
        view_requires_login=True,
    )
    await asyncio.to_thread(
        UsersFile(settings.web.users_path).add, "ann", Role.VIEWER, "pw-ann-123"
    )
    async with _plant_app(settings) as base, httpx.AsyncClient(base_url=base) as client:
        refused = await client.get("/api/v1/plant/nodes")
        assert refused.status_code == 401
        bad = await client.post("/api/v1/auth/login", json={"username": "ann", "password": "wrong"})
        assert bad.status_code == 401
        login = await client.post(
            "/api/v1/auth/login", json={"username": "ann", "password": "pw-ann-123"}
        )
        assert login.status_code == 200
        headers = {"Authorization": f"Bearer {login.json()['token']}"}
        assert (await client.get("/api/v1/plant/nodes", headers=headers)).json() == []
        status = (await client.get("/api/v1/plant/status", headers=headers)).json()
        assert status["broker"] is None
        assert (await client.get("/healthz")).status_code == 503
        # The service's Host check: a name this host is not called is refused.
        forged = await client.get(
            "/api/v1/plant/nodes", headers={**headers, "Host": "evil.example"}
        )
        assert forged.status_code in (400, 421)
