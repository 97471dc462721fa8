"""``cobot-hmi plant`` (a real process) on a real Mosquitto, read through its REST API: our own
cell's edge node (the Sparkplug tests' cell: emulated robots, the service, its edge node) and
an edge node we did not write (pysparkplug), which the plant shows, asks for a rebirth after a
planted seq gap, and marks offline on its NDEATH."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from cobot_hmi.layout import robot_state_name
from mosquitto_support import mosquitto, needs_mosquitto
from plant_support import needs_pysparkplug, plant_process, pysparkplug_node
from sparkplug_support import GROUP, NODE, cell
from waiting import eventually_async

HOST_ID = "cobot-hmi-plant"
"""The plant's host id by default."""

pytestmark = [needs_mosquitto, pytest.mark.timeout(120)]


@needs_pysparkplug
async def test_an_independent_edge_node_is_shown_rebirthed_and_buried(
    plc_host: str, tmp_path: Path
) -> None:
    async with (
        mosquitto(plc_host, tmp_path) as broker,
        plant_process(plc_host, tmp_path / "plant", [broker.url]) as plant,
        pysparkplug_node(plc_host, broker.port, "line-3", "tahu-like", "r1") as peer,
    ):
        node = await plant.until(
            "line-3",
            "tahu-like",
            lambda n: n["online"] and n["devices"] and n["devices"][0]["online"],
        )
        assert node["area"] == "paint shop"
        device = node["devices"][0]
        assert device["device"] == "r1"
        assert device["state"] == "STANDALONE_RUNNING"
        assert device["state_group"] == "running"
        assert device["alarms_active"] == []
        assert device["cycle_last_s"] == pytest.approx(12.5)

        started = time.time()
        await peer.send("data r1 Alarm/overheat/Active true")
        node = await plant.until("line-3", "tahu-like", lambda n: n["devices"][0]["alarms_active"])
        [alarm] = node["devices"][0]["alarms_active"]
        assert (alarm["priority"], alarm["text"]) == ("high", "Motor overheated")
        alarms = await plant.get("/api/v1/plant/alarms", since=started - 5)
        assert [
            (t["node"], t["device"], t["alarm"], t["active"]) for t in alarms["transitions"]
        ] == [("tahu-like", "r1", "overheat", True)]

        # A seq the plant never sees: the next DDATA is a gap, answered with a rebirth request
        # that the peer itself receives (its NCMD callback).
        await peer.send("gap")
        await peer.send('data r1 robot_state "STANDALONE_STANDBY"')
        await peer.wait_for("ncmd Node Control/Rebirth=True")
        status = await plant.get("/api/v1/plant/status")
        assert status["rebirths"].get("seq gap") == 1
        node = await plant.until(
            "line-3", "tahu-like", lambda n: n["devices"][0]["state"] == "STANDALONE_STANDBY"
        )

        # Its NDEATH: the will the broker publishes when its connection drops (pysparkplug
        # 0.6.1's clean disconnect sends an NDEATH whose bdSeq is one past its NBIRTH's, which a
        # host must not take for this session's: the will carries the NBIRTH's).
        peer.process.kill()
        node = await plant.until("line-3", "tahu-like", lambda n: not n["online"])
        assert not node["devices"][0]["online"]
        assert node["devices"][0]["state"] == "STANDALONE_STANDBY"  # its last values kept
        assert node["since"] >= started - 1

        # What the plant received is in its history (the hour's Parquet segment on disk).
        async def recorded() -> bool:
            points = await plant.get(
                "/api/v1/plant/trend",
                group="line-3",
                node="tahu-like",
                device="r1",
                metric="robot_state",
                since=started - 60,
            )
            texts = [p["text"] for p in points]
            return "STANDALONE_RUNNING" in texts and "STANDALONE_STANDBY" in texts

        await eventually_async(recorded)
        shift = await plant.get(
            "/api/v1/plant/shift", group="line-3", node="tahu-like", device="r1", since=started
        )
        assert shift["seconds"]["running"] > 0 and shift["seconds"]["standby"] > 0
        assert shift["seconds"]["unknown"] == 0
        assert sum(shift["seconds"].values()) == pytest.approx(time.time() - started, abs=5)
        assert list((tmp_path / "plant" / "plant-history").glob("*/*.parquet"))


async def test_our_cell_is_shown_with_its_robots_in_words(plc_host: str, tmp_path: Path) -> None:
    # The cell names the plant its primary host application: it is born when the plant's
    # STATE says it is online (Sparkplug 3.0), so the plant sees every birth.
    async with (
        cell(tmp_path, plc_host, wait_births=False, sparkplug_primary_host=HOST_ID) as c,
        plant_process(plc_host, tmp_path / "plant", [c.broker.url]) as plant,
    ):
        node = await plant.until(
            GROUP,
            NODE,
            lambda n: (
                n["online"] and len(n["devices"]) == 2 and all(d["online"] for d in n["devices"])
            ),
        )
        states = {d["device"]: d["state"] for d in node["devices"]}
        frame = c.frames_seen("m1013")[-1].frame
        assert states["m1013"] == robot_state_name(frame.robot_state)
        c.panels["m1013"].set(robot_state=3)
        await plant.until(
            GROUP,
            NODE,
            lambda n: {d["device"]: d["state"] for d in n["devices"]}["m1013"] == "INTERRUPTED",
        )
        await c.stop_robot("m0609")
        node = await plant.until(
            GROUP,
            NODE,
            lambda n: not {d["device"]: d["online"] for d in n["devices"]}["m0609"],
        )
        assert node["online"]
        filtered = await plant.nodes(state="stopped")
        devices = [d for n in filtered for d in n["devices"]]
        assert "m1013" in [d["device"] for d in devices]
        assert {d["state_group"] for d in devices} == {"stopped"}
