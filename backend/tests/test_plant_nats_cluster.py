"""The plant on a broker cluster: three ``nats-server`` nodes (v2.15.3, MQTT on JetStream,
clustered; ``make peers`` builds it), our cell's edge node on one node, an edge node we did not
write (pysparkplug) on the same node, the plant on the other two (``--mqtt-url`` twice). The
node the plant is connected to is killed (SIGKILL): the plant moves to the other, asks for the
rebirths its seq checks call for, and shows the cell as it is now.

NATS's MQTT: QoS 0 and 1 (no 2), retained messages and wills kept in JetStream, a server name
and JetStream on every node (docs/operations.md "The plant").

The tests share one cluster (starting three nodes and their JetStream is most of a test's time):
each test gets it with every node up and taking MQTT clients, a node the previous test killed
started again on its own store (it rejoins the cluster); each test has its own cell, plant and
client ids' sessions are clean."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import signal
import socket
import subprocess
import time
from collections.abc import AsyncIterator, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from conftest import _next_host, free_tcp_port
from plant_support import needs_pysparkplug, plant_process, pysparkplug_node
from service_support import Running, cell_settings, running_service
from sparkplug_support import Panel, edge_node_of
from waiting import eventually, eventually_async

REPO = Path(__file__).resolve().parents[2]
NATS_SERVER = REPO / ".venv" / "go-bin" / "nats-server"
HOST_ID = "cobot-hmi-plant"
GROUP, NODE = "plant", "cell-7"

pytestmark = [
    pytest.mark.skipif(not NATS_SERVER.exists(), reason="nats-server (make peers)"),
    pytest.mark.timeout(180),
]


@dataclass
class NatsNode:
    name: str
    host: str
    mqtt_port: int
    config: Path
    process: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"mqtt://{self.host}:{self.mqtt_port}"

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def start(self) -> None:
        self.process = subprocess.Popen(
            [str(NATS_SERVER), "-c", str(self.config)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )

    def kill(self) -> None:
        """SIGKILL, and the process reaped (a killed node is started again by ``cluster``)."""
        if self.running:
            assert self.process is not None
            self.process.send_signal(signal.SIGKILL)
            self.process.wait()


def _mqtt_accepts(node: NatsNode) -> bool:
    """A CONNECT answered with a CONNACK accepting it (NATS's MQTT refuses clients until its
    JetStream is up)."""
    connect = bytes.fromhex("101000044d5154540402003c0004") + b"wait"
    try:
        with socket.create_connection((node.host, node.mqtt_port), timeout=2) as sock:
            sock.sendall(connect)
            sock.settimeout(5)
            answer = sock.recv(4)
    except OSError:
        return False
    return answer[:1] == b"\x20" and answer[3:4] == b"\x00"


@pytest.fixture(scope="module")
def nats_nodes(tmp_path_factory: pytest.TempPathFactory) -> Iterator[list[NatsNode]]:
    """Three clustered nodes for the module's tests, started (``cluster`` waits for them)."""
    directory = tmp_path_factory.mktemp("nats")
    hosts = [_next_host() for _ in range(3)]
    cluster_ports = [free_tcp_port(h) for h in hosts]
    routes = ", ".join(f"nats-route://{h}:{p}" for h, p in zip(hosts, cluster_ports, strict=True))
    nodes = []
    for index, host in enumerate(hosts):
        name = f"n{index + 1}"
        config = directory / f"{name}.conf"
        mqtt_port = free_tcp_port(host)
        config.write_text(
            f"server_name: {name}\n"
            f"listen: {host}:{free_tcp_port(host)}\n"
            f'jetstream {{ store_dir: "{directory / name}" }}\n'
            f"cluster {{ name: plant, listen: {host}:{cluster_ports[index]}, "
            f"routes: [{routes}] }}\n"
            f"mqtt {{ listen: {host}:{mqtt_port} }}\n"
        )
        nodes.append(NatsNode(name, host, mqtt_port, config))
    try:
        for node in nodes:
            node.start()
        yield nodes
    finally:
        for node in nodes:
            node.kill()


@pytest.fixture
async def cluster(nats_nodes: list[NatsNode]) -> list[NatsNode]:
    """The module's cluster with every node up: one a previous test killed started again."""
    for node in nats_nodes:
        if not node.running:
            node.start()
    for node in nats_nodes:
        await eventually(functools.partial(_mqtt_accepts, node), timeout_s=60)
    return nats_nodes


@contextlib.asynccontextmanager
async def our_cell(
    plc_host: str, directory: Path, url: str
) -> AsyncIterator[tuple[dict[str, Panel], Running]]:
    """Two emulated robots and the service, its edge node on ``url``, the plant its primary
    host application."""
    panels = {"m1013": Panel(), "m0609": Panel()}
    targets = []
    robots = []
    try:
        for name, panel in panels.items():
            host = _next_host()
            port = free_tcp_port(host)
            target = Target(TargetSettings(host=host, tcp_port=port), panel)
            await target.start()
            targets.append(target)
            robots.append((name, host, port))
        settings = cell_settings(
            robots,
            plc_host,
            directory,
            mqtt_url=url,
            sparkplug_group=GROUP,
            sparkplug_node=NODE,
            sparkplug_primary_host=HOST_ID,
        )
        async with running_service(settings) as running:
            yield panels, running
    finally:
        for target in targets:
            await target.stop()


def _devices(node: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {d["device"]: d for d in node["devices"]}


@needs_pysparkplug
async def test_killing_the_plants_broker_node(
    plc_host: str, tmp_path: Path, cluster: list[NatsNode]
) -> None:
    a, b, c = cluster
    async with (
        our_cell(plc_host, tmp_path / "cell", a.url) as (panels, _),
        plant_process(plc_host, tmp_path / "plant", [b.url, c.url]) as plant,
        pysparkplug_node(a.host, a.mqtt_port, "line-3", "foreign", "r1") as peer,
    ):
        node = await plant.until(
            GROUP, NODE, lambda n: n["online"] and all(d["online"] for d in n["devices"])
        )
        assert len(node["devices"]) == 2
        await plant.until("line-3", "foreign", lambda n: n["online"])
        status = await plant.get("/api/v1/plant/status")
        assert status["broker"] == f"{b.host}:{b.mqtt_port}"

        await peer.send("data r1 Alarm/overheat/Active true")
        await plant.until("line-3", "foreign", lambda n: n["devices"][0]["alarms_active"])

        killed_at = time.time()
        b.kill()
        # Meanwhile the cell and the foreign node go on: what they publish while the plant has
        # no connection is lost to it, and its seq check notices.
        panels["m1013"].set(robot_state=3)
        await peer.send("data r1 Alarm/overheat/Active false")

        async def on_c() -> bool:
            answer = await plant.get("/api/v1/plant/status")
            return bool(answer["broker"] == f"{c.host}:{c.mqtt_port}")

        await eventually_async(on_c, timeout_s=60)
        panels["m1013"].set(robot_state=2)  # after the move: seen live
        await peer.send('data r1 robot_state "STANDALONE_STANDBY"')
        try:
            await plant.until(
                GROUP, NODE, lambda n: _devices(n)["m1013"]["state"] == "SAFE_OFF", timeout_s=40
            )
        except AssertionError as error:
            status = await plant.get("/api/v1/plant/status")
            raise AssertionError(f"{error}\npeer: {peer.lines}\nplant: {status}") from None
        try:
            await plant.until(
                "line-3",
                "foreign",
                lambda n: n["devices"][0]["state"] == "STANDALONE_STANDBY",
                timeout_s=60,
            )
        except AssertionError as error:
            status = await plant.get("/api/v1/plant/status")
            raise AssertionError(f"{error}\npeer: {peer.lines}\nplant: {status}") from None
        status = await plant.get("/api/v1/plant/status")
        assert status["connections_lost"] >= 1
        # Whether a node's messages were lost to the plant depends on how fast it moved (it
        # sees the node's socket close at once) and on whether the cluster dropped the edge
        # nodes too: a gap is answered with a rebirth (the planted gap of test_plant_mosquitto
        # shows it every time), a node's own reconnection brings its births. Either way the
        # foreign node's alarm, cleared while the plant had no connection, is cleared at the
        # plant too, and the clearing is in the plant's alarm list at the node's own time.
        await plant.until(
            "line-3", "foreign", lambda n: n["devices"][0]["alarms_active"] == [], timeout_s=60
        )
        alarms = await plant.get("/api/v1/plant/alarms", since=killed_at - 60)
        foreign_transitions = [
            (t["alarm"], t["active"])
            for t in reversed(alarms["transitions"])
            if t["node"] == "foreign"
        ]
        assert foreign_transitions == [("overheat", True), ("overheat", False)]


class AlarmToggler:
    """A robot's protective stop, on and off, each change once the cell's own alarm engine has
    seen the previous one and its edge node has published it (no sleeps: at the pace of the
    edge node's reports, ten a second)."""

    def __init__(self, panel: Panel, running: Running, robot: str) -> None:
        self.panel = panel
        self.engine = running.service.robots[robot].alarms
        edge = edge_node_of(running.service)
        assert edge is not None
        self.device = edge.devices[robot]
        self.changes = 0
        self.stopped = asyncio.Event()

    def active(self) -> bool:
        return self.engine.snapshot_of("protective_stop")["active"] is True

    async def toggle(self) -> None:
        want = not self.active()
        self.panel.set(robot_state=3 if want else 13)  # INTERRUPTED / STANDALONE_STANDBY
        await eventually(lambda: self.active() == want, timeout_s=30)
        self.changes += 1
        await eventually(lambda: not self.device.event_changes, timeout_s=30)

    async def run(self) -> None:
        while not self.stopped.is_set():
            await self.toggle()


async def _cell_transitions(running: Running, since: float) -> set[tuple[str, str, bool, int]]:
    """The cell's own alarm history (its REST API): each activation and clearing."""
    async with running.client() as client:
        answer = await client.get("/api/v1/alarms/history", params={"since": since, "limit": 1000})
    assert answer.status_code == 200, answer.text
    return {
        # In ms as the edge node stamps them (the same float, truncated).
        (row["robot"], row["key"], row["transition"] == "activated", int(row["time"] * 1000))
        for row in answer.json()["items"]
        if row["transition"] in ("activated", "cleared")
    }


async def _plant_transitions(plant: Any, since: float) -> set[tuple[str, str, bool, int]]:
    answer = await plant.get("/api/v1/plant/alarms", since=since, limit=5000)
    return {
        (t["device"], t["alarm"], t["active"], round(t["time"] * 1000))
        for t in answer["transitions"]
        if t["node"] == NODE
    }


async def test_no_alarm_transition_is_lost_when_the_plants_node_dies(
    plc_host: str, tmp_path: Path, cluster: list[NatsNode]
) -> None:
    """The cell publishes alarm transitions without pause while the node the plant is connected
    to is killed: the plant moves to another node, asks for a rebirth with the transitions it
    missed, and its alarm log ends equal to the cell's own alarm history."""
    a, b, c = cluster
    async with (
        our_cell(plc_host, tmp_path / "cell", a.url) as (panels, running),
        plant_process(plc_host, tmp_path / "plant", [b.url, c.url]) as plant,
    ):
        await plant.until(
            GROUP, NODE, lambda n: n["online"] and all(d["online"] for d in n["devices"])
        )
        started = time.time()
        toggler = AlarmToggler(panels["m1013"], running, "m1013")
        for _ in range(4):
            await toggler.toggle()
        await plant.until(GROUP, NODE, lambda n: _devices(n)["m1013"]["alarms_active"] == [])
        task = asyncio.create_task(toggler.run())
        try:
            before_kill = toggler.changes
            b.kill()

            async def on_c() -> bool:
                answer = await plant.get("/api/v1/plant/status")
                return bool(answer["broker"] == f"{c.host}:{c.mqtt_port}")

            await eventually_async(on_c, timeout_s=60)
            during = toggler.changes - before_kill
            after_move = toggler.changes
            await eventually(lambda: toggler.changes >= after_move + 4, timeout_s=60)
        finally:
            toggler.stopped.set()
            await task
        if toggler.active():
            await toggler.toggle()  # end cleared

        async def equal() -> bool:
            cell = await _cell_transitions(running, started - 1)
            seen = await _plant_transitions(plant, started - 1)
            return bool(cell) and cell == seen

        try:
            await eventually_async(equal, timeout_s=90)
        except AssertionError:
            cell = await _cell_transitions(running, started - 1)
            seen = await _plant_transitions(plant, started - 1)
            status = await plant.get("/api/v1/plant/status")
            raise AssertionError(
                f"missing at the plant: {sorted(cell - seen)}\nonly at the plant: "
                f"{sorted(seen - cell)}\n{during} changes while moving; plant: {status}"
            ) from None
        cell = await _cell_transitions(running, started - 1)
        assert len(cell) >= toggler.changes
        status = await plant.get("/api/v1/plant/status")
        assert status["connections_lost"] >= 1
        assert status["rebirths"].get("reconnect", 0) >= 1
