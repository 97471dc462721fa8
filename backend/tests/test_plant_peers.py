"""A plant split by Sparkplug group over two ``cobot-hmi plant`` processes (issue 41 "Scale
out"), one page over both: two real processes on a real Mosquitto, each following its own group
(``--group``), the first naming the second its peer (``--peer``) and a third that accepts
connections and never answers. The first's ``/api/v1/plant/nodes`` answers both groups' edge
nodes (each independent edge node in its group), its alarm list both groups' alarms; the hung
peer is said to be down and never holds an answer; a trend of the second's robot asked of the
first is the second's; the second killed, it is said to be down and its cells are kept as last
answered, while the first answers on."""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.plant.plant_settings import PlantSettings
from cobot_hmi.service.service_settings import SettingsError
from conftest import free_tcp_port
from mosquitto_support import mosquitto, needs_mosquitto
from plant_support import Plant, needs_pysparkplug, plant_process, pysparkplug_node
from waiting import eventually_async

pytestmark = [needs_mosquitto, needs_pysparkplug, pytest.mark.timeout(180)]


@contextlib.asynccontextmanager
async def _silent_server(host: str) -> AsyncIterator[str]:
    """A peer that accepts connections and never answers (a hung process)."""
    held: list[asyncio.StreamWriter] = []

    async def hold(_: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        held.append(writer)

    port = free_tcp_port(host)
    server = await asyncio.start_server(hold, host, port)
    try:
        yield f"http://{host}:{port}"
    finally:
        server.close()
        for writer in held:
            writer.close()
        await server.wait_closed()


async def _groups(plant: Plant) -> dict[tuple[str, str], Any]:
    return {(n["group"], n["node"]): n for n in await plant.nodes()}


async def _peer(plant: Plant, url: str) -> dict[str, Any]:
    peers = await plant.get("/api/v1/plant/peers")
    return next(p for p in peers if p["url"] == url)


def test_a_peer_is_an_http_url(tmp_path: Path) -> None:
    settings = PlantSettings.from_keys(
        state_dir=tmp_path, plant_peers="http://127.0.0.1:8101,https://plant-2.example:8443/"
    )
    assert settings.plant.plant_peers == ["http://127.0.0.1:8101", "https://plant-2.example:8443/"]
    for wrong in ("ftp://plant-2:21", "plant-2:8101", "http://"):
        with pytest.raises((SettingsError, ValueError), match="a peer is http"):
            PlantSettings.from_keys(state_dir=tmp_path, plant_peers=[wrong])


async def test_one_plant_process_answers_for_its_peer_on_another_group(
    plc_host: str, tmp_path: Path
) -> None:
    async with (
        mosquitto(plc_host, tmp_path) as broker,
        _silent_server(plc_host) as hung,
        plant_process(
            plc_host, tmp_path / "east", [broker.url], "--group", "east", "--plant-host-id", "east"
        ) as east,
        plant_process(
            plc_host,
            tmp_path / "west",
            [broker.url],
            *("--group", "west", "--plant-host-id", "west"),
            *("--peer", east.base_url, "--peer", hung),
        ) as west,
        pysparkplug_node(plc_host, broker.port, "west", "cell-w", "r1") as cell_w,
        pysparkplug_node(plc_host, broker.port, "east", "cell-e", "r1") as cell_e,
    ):
        # Each process follows its own group only; the west's page shows both.
        await east.until("east", "cell-e", lambda n: n["online"])
        await west.until("west", "cell-w", lambda n: n["online"])
        node = await west.until("east", "cell-e", lambda n: n["online"] and n["devices"])
        assert node["peer"] == east.base_url
        assert node["devices"][0]["state"] == "STANDALONE_RUNNING"
        assert set(await _groups(east)) == {("east", "cell-e")}
        both = await _groups(west)
        assert set(both) == {("east", "cell-e"), ("west", "cell-w")}
        assert both["west", "cell-w"]["peer"] is None
        # Filters hold for a peer's nodes as for its own.
        assert [n["node"] for n in await west.nodes(group="east")] == ["cell-e"]
        assert [n["node"] for n in await west.nodes(state="running")] == ["cell-e", "cell-w"]
        assert await west.nodes(local="true") == [both["west", "cell-w"]]

        # An alarm in each group: both in the west's alarm list, newest first.
        started = time.time()
        await cell_w.send("data r1 Alarm/overheat/Active true")
        await cell_e.send("data r1 Alarm/overheat/Active true")

        async def both_alarms() -> bool:
            answer = await west.get("/api/v1/plant/alarms", since=started - 5)
            return {t["node"] for t in answer["transitions"]} == {"cell-w", "cell-e"}

        await eventually_async(both_alarms, 30.0)
        answer = await west.get("/api/v1/plant/alarms", since=started - 5)
        times = [t["time"] for t in answer["transitions"]]
        assert times == sorted(times, reverse=True)
        assert {f["node"] for f in answer["figures"]} == {"cell-w", "cell-e"}
        shifts = await west.get("/api/v1/plant/shifts")
        assert {(r["group"], r["node"]) for r in shifts["robots"]} >= {
            ("west", "cell-w"),
            ("east", "cell-e"),
        }

        # A trend of the east's robot, asked of the west: the east's history answers it.
        trend = {"group": "east", "node": "cell-e", "device": "r1", "metric": "robot_state"}

        async def east_trend() -> bool:
            points = await west.get("/api/v1/plant/trend", since=started - 3600, **trend)
            return any(p["text"] == "STANDALONE_RUNNING" for p in points)

        await eventually_async(east_trend, 30.0)
        theirs = await east.get("/api/v1/plant/trend", since=started - 3600, **trend)
        ours = await west.get("/api/v1/plant/trend", since=started - 3600, **trend)
        assert [p["time"] for p in ours] == [p["time"] for p in theirs[: len(ours)]]
        local = {**trend, "local": "true"}
        assert await west.get("/api/v1/plant/trend", since=started - 3600, **local) == []

        # The hung peer: said not to answer, with why; it held no answer meanwhile.
        hung_peer = await _peer(west, hung)
        assert not hung_peer["answering"] and "timed out" in hung_peer["error"]
        assert (await _peer(west, east.base_url))["answering"]

        # The east process killed: the west says so, keeps its cells as last answered,
        # and answers on for its own.
        east.process.kill()

        async def east_down() -> bool:
            return not (await _peer(west, east.base_url))["answering"]

        await eventually_async(east_down, 30.0)
        down = await _peer(west, east.base_url)
        assert down["error"] and down["nodes"] == 1 and down["since"] >= started - 1
        kept = await _groups(west)
        assert kept["east", "cell-e"]["peer"] == east.base_url
        await cell_w.send('data r1 robot_state "STANDALONE_STANDBY"')
        await west.until(
            "west", "cell-w", lambda n: n["devices"][0]["state"] == "STANDALONE_STANDBY"
        )
        answer = await west.get("/api/v1/plant/alarms", since=started - 5)
        assert {t["node"] for t in answer["transitions"]} == {"cell-w"}
        refused = await west.client.get(
            "/api/v1/plant/trend", params={"since": started - 3600, **trend}
        )
        assert refused.status_code == 502, refused.text
        assert east.base_url in refused.json()["detail"]["reason"]
