"""What the plant page needs of ``cobot-hmi plant``'s web app: ``/`` leads to the page
(``/plant``, the frontend's plant face), ``/api/v1/plant/shifts`` answers every robot over the
shift in progress, the shift's start as the kiosk reckons it, and the plant's OpenAPI document
committed for the frontend's generated types (``docs/plant-openapi.json``) is fresh."""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator
from datetime import datetime
from pathlib import Path
from zoneinfo import ZoneInfo

import httpx
import pytest
import uvicorn

from cobot_hmi.cli import main as cli_main
from cobot_hmi.cli.openapi_verb import PLANT_OUTPUT, render
from cobot_hmi.plant.app import create_plant_app
from cobot_hmi.plant.plant_settings import PlantSettings
from cobot_hmi.plant.routes import shift_start
from cobot_hmi.plant.runtime import PlantRuntime
from conftest import free_tcp_port
from waiting import eventually

BERLIN = ZoneInfo("Europe/Berlin")
STARTS = ["06:00", "14:00", "22:00"]


def test_the_shift_in_progress_began_at_the_last_start_passed() -> None:
    def at(day: int, hour: int, minute: int = 0) -> datetime:
        return datetime(2026, 3, day, hour, minute, tzinfo=BERLIN)

    assert shift_start(at(10, 9, 30), STARTS) == at(10, 6)
    assert shift_start(at(10, 14), STARTS) == at(10, 14)  # a shift begins on its minute
    assert shift_start(at(10, 23, 59), STARTS) == at(10, 22)
    assert shift_start(at(10, 5, 59), STARTS) == at(9, 22)  # the night shift began yesterday
    assert shift_start(at(1, 0, 30), ["06:00"]) == datetime(2026, 2, 28, 6, tzinfo=BERLIN)


def test_the_committed_plant_document_is_fresh() -> None:
    assert PLANT_OUTPUT.is_file(), f"run: cobot-hmi openapi --plant --output {PLANT_OUTPUT}"
    assert PLANT_OUTPUT.read_text(encoding="utf-8") == render(plant=True), (
        f"stale: run cobot-hmi openapi --plant --output {PLANT_OUTPUT}"
    )
    assert cli_main(["openapi", "--plant", "--check"]) == 0


@contextlib.asynccontextmanager
async def _plant_app(settings: PlantSettings, base: str) -> AsyncIterator[str]:
    host, port = base.removeprefix("http://").split(":")
    config = uvicorn.Config(
        create_plant_app(PlantRuntime(settings)),
        host=host,
        port=int(port),
        log_level="warning",
        lifespan="on",
    )
    server = uvicorn.Server(config)
    task = asyncio.create_task(server.serve())
    try:
        await eventually(lambda: server.started or task.done())
        assert not task.done()
        yield base
    finally:
        server.should_exit = True
        await task


@pytest.mark.timeout(60)
async def test_root_leads_to_the_page_and_shifts_answer(plc_host: str, tmp_path: Path) -> None:
    port = free_tcp_port(plc_host)
    settings = PlantSettings.from_keys(
        host=plc_host,
        port=port,
        state_dir=tmp_path,
        mqtt_urls=[f"mqtt://{plc_host}:{free_tcp_port(plc_host)}"],  # no broker: it retries
        time_zone="Europe/Berlin",
        shift_starts=STARTS,
    )
    base = f"http://{plc_host}:{port}"
    async with _plant_app(settings, base), httpx.AsyncClient(base_url=base) as client:
        root = await client.get("/")
        assert (root.status_code, root.headers["location"]) == (307, "/plant")
        answer = (await client.get("/api/v1/plant/shifts")).json()
        now = datetime.now(BERLIN)
        assert answer["time_zone"] == "Europe/Berlin"
        assert answer["since"] == shift_start(now, STARTS).timestamp()
        assert answer["since"] <= answer["until"] <= now.timestamp() + 1
        assert answer["robots"] == []
