"""The OPC UA server (issue 22) seen by an independent client: node-opcua (npm, tests/peers).

One cell for the module: two simulated robots in this process ("still", an M1013 whose program
the tests stop, with its control API; "moving", an M0609 running its program), the service
holding both with OPC UA on its own loopback address (writes on), and one node-opcua process
with three sessions: anonymous over None, the operator over SignAndEncrypt, the viewer over
Sign. The tests that write take and release control themselves; the emulator restart comes
last and ends with the robot back.
"""

from __future__ import annotations

import asyncio
import contextlib
import xml.etree.ElementTree as ET
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
import pytest_asyncio

from cobot_hmi.emulator.control_api import ControlApiServer, create_control_app
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings, default_identity
from cobot_hmi.opcua.feed import ServiceFeed
from cobot_hmi.opcua.server import OpcUaServer
from cobot_hmi.opcua.units import unit_for
from conftest import _next_host as next_host
from conftest import free_tcp_port
from emulator_harness import FAST_TIMINGS
from opcua_support import (
    ROBOTICS_NODESET,
    OpcUaPeer,
    PeerError,
    client_certificate,
    trust,
)
from service_support import OPERATOR, VIEWER, Running, cell_settings, eventually, running_service

pytestmark = [pytest.mark.timeout(300), pytest.mark.asyncio(loop_scope="module")]

ROBOTICS_URI = "http://opcfoundation.org/UA/Robotics/"
DI_URI = "http://opcfoundation.org/UA/DI/"
UA_NS = "{http://opcfoundation.org/UA/2011/03/UANodeSet.xsd}"
CONTAINMENT = ("ns=0;i=47", "ns=0;i=46", "ns=0;i=35")
"""HasComponent, HasProperty, Organizes."""
MANDATORY = "i=78"
MANDATORY_PLACEHOLDER = "i=11510"


@dataclass
class Cell:
    running: Running
    still: SimulatedRobot
    control_url: str
    moving: SimulatedRobot
    moving_target: Target
    peer: OpcUaPeer
    namespaces: list[str]
    endpoint: str
    certificate: tuple[Path, Path]
    state_dir: Path

    def ns(self, uri: str) -> int:
        return self.namespaces.index(uri)

    def node(self, robot: str, path: str) -> str:
        """A robot's node by its NodeId string (``m1013.Frame.robot_state``)."""
        return f"ns={self.ns('urn:cobot-hmi:robot:' + robot)};s={robot}.{path}"


@contextlib.asynccontextmanager
async def _cell(state_dir: Path) -> AsyncIterator[Cell]:
    plc_host, still_host, moving_host = next_host(), next_host(), next_host()
    still = SimulatedRobot(RobotSettings(timings=FAST_TIMINGS))
    moving = SimulatedRobot(RobotSettings(model="M0609", seed=2, timings=FAST_TIMINGS))
    still_target = Target(TargetSettings(host=still_host, tcp_port=0), still)
    moving_settings = TargetSettings(
        host=moving_host, tcp_port=0, identity=default_identity("M0609")
    )
    moving_target = Target(moving_settings, moving)
    await still_target.start()
    await moving_target.start()
    control = ControlApiServer(
        create_control_app(still, still_target), still_host, free_tcp_port(still_host)
    )
    await control.start()
    port = free_tcp_port(plc_host)
    endpoint = f"opc.tcp://{plc_host}:{port}"
    settings = cell_settings(
        [
            ("still", still_host, still_target.tcp_port),
            ("moving", moving_host, moving_target.tcp_port),
        ],
        plc_host,
        state_dir,
        opcua_url=endpoint,
        opcua_writes=True,
        write_timeout_ms=10_000.0,
    )
    certificate = client_certificate(state_dir / "client")
    trust(certificate[0], settings.opcua.opcua_trusted_dir(state_dir))
    peer = await OpcUaPeer.start(state_dir / "node-pki")
    targets = [still_target, moving_target]
    try:
        async with running_service(settings) as running:
            await peer.connect("anonymous", endpoint)
            await peer.connect(
                "operator", endpoint, mode="SignAndEncrypt", user=OPERATOR, certificate=certificate
            )
            await peer.connect(
                "viewer", endpoint, mode="Sign", user=VIEWER, certificate=certificate
            )
            namespaces = await peer.request("namespaces", name="anonymous")
            cell = Cell(
                running,
                still,
                f"http://{still_host}:{control.port}",
                moving,
                moving_target,
                peer,
                namespaces,
                endpoint,
                certificate,
                state_dir,
            )
            yield cell
            targets.append(cell.moving_target)
    finally:
        await peer.close()
        await control.stop()
        for target in targets:
            await target.stop()


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def cell(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Cell]:
    async with _cell(tmp_path_factory.mktemp("opcua-cell")) as running:
        yield running


# --------------------------------------------------------------------------- the official model


def _official_types() -> tuple[dict[str, str], dict[str, list[tuple[str, str, str]]]]:
    """From node-opcua-nodesets' Robotics NodeSet: type NodeId (its own namespace's index as
    the file numbers it) → browse name; type NodeId → its declared members (browse name,
    modelling rule, type definition)."""
    root = ET.parse(ROBOTICS_NODESET).getroot()
    uris = [uri.text for uri in root.find(f"{UA_NS}NamespaceUris") or []]
    robotics_index = uris.index(ROBOTICS_URI) + 1
    aliases = {str(a.get("Alias")): str(a.text) for a in root.find(f"{UA_NS}Aliases") or []}
    nodes = {str(el.get("NodeId")): el for el in root if el.get("NodeId")}

    def refs(element: ET.Element) -> list[tuple[str, str, str]]:
        found = []
        for reference in element.find(f"{UA_NS}References") or []:
            kind = reference.get("ReferenceType") or ""
            found.append(
                (aliases.get(kind, kind), reference.get("IsForward", "true"), reference.text or "")
            )
        return found

    types: dict[str, str] = {}
    members: dict[str, list[tuple[str, str, str]]] = {}
    for node_id, element in nodes.items():
        if element.tag != f"{UA_NS}UAObjectType" or not node_id.startswith(f"ns={robotics_index};"):
            continue
        types[node_id] = (element.get("BrowseName") or "").split(":", 1)[1]
        declared = []
        for kind, forward, target in refs(element):
            if forward != "true" or kind not in ("i=47", "i=46", "HasComponent", "HasProperty"):
                continue
            child = nodes.get(target)
            if child is None:
                continue
            rule = next((t for k, f, t in refs(child) if k in ("i=37", "HasModellingRule")), "")
            type_definition = next(
                (t for k, f, t in refs(child) if k in ("i=40", "HasTypeDefinition")), ""
            )
            declared.append(
                ((child.get("BrowseName") or "").split(":", 1)[-1], rule, type_definition)
            )
        members[node_id] = declared
    return {_numeric(k): v for k, v in types.items()}, {_numeric(k): v for k, v in members.items()}


def _numeric(node_id: str) -> str:
    return node_id.split(";", 1)[1]


async def test_device_set_is_the_robotics_model(cell: Cell) -> None:
    """Every robot is a MotionDeviceSystemType in DeviceSet, its parts the specification's
    types (NodeId and browse name as the official NodeSet gives them), each with its mandatory
    members and at least one of each mandatory placeholder."""
    types, members = _official_types()
    robotics = cell.ns(ROBOTICS_URI)
    browsed = await cell.peer.request(
        "browse_tree", name="anonymous", root=f"ns={cell.ns(DI_URI)};i=5001"
    )
    # The containment tree (Controls, Moves, Requires … are hierarchical too, not parts).
    tree = [node for node in browsed if node["referenceType"] in CONTAINMENT]
    by_path = {node["path"]: node for node in tree}
    children: dict[str, list[dict[str, Any]]] = {}
    for node in tree:
        children.setdefault(node["path"].rsplit("/", 1)[0], []).append(node)
    checked = 0
    for node in tree:
        type_definition = node["typeDefinition"] or ""
        if not type_definition.startswith(f"ns={robotics};"):
            continue
        numeric = _numeric(type_definition)
        assert numeric in types, f"{node['path']}: {type_definition} is no Robotics type"
        names = {child["browseName"]["name"] for child in children.get(node["path"], [])}
        for name, rule, member_type in members[numeric]:
            if rule == MANDATORY:
                assert name in names, f"{node['path']} ({types[numeric]}) lacks {name}"
            elif rule == MANDATORY_PLACEHOLDER:
                holder = node["path"]
                expected = _numeric(member_type) if member_type.startswith("ns=") else None
                found = [
                    c
                    for c in children.get(holder, [])
                    if expected is None or _numeric(c["typeDefinition"] or "") == expected
                ]
                assert found, f"{holder} ({types[numeric]}) has no {name}"
        checked += 1
    for robot in ("still", "moving"):
        r = cell.ns("urn:cobot-hmi:robot:" + robot)
        base = f"/{r}:{robot}"
        expect = {
            base: "MotionDeviceSystemType",
            f"{base}/{robotics}:MotionDevices/{r}:{robot}": "MotionDeviceType",
            f"{base}/{robotics}:Controllers/{r}:{robot}": "ControllerType",
            f"{base}/{robotics}:SafetyStates/{r}:{robot}": "SafetyStateType",
        }
        device = f"{base}/{robotics}:MotionDevices/{r}:{robot}"
        for joint in range(1, 7):
            expect[f"{device}/{robotics}:Axes/{r}:Axis{joint}"] = "AxisType"
            train = f"{device}/{robotics}:PowerTrains/{r}:PowerTrain{joint}"
            expect[train] = "PowerTrainType"
            expect[f"{train}/{r}:Motor1"] = "MotorType"
        for path, type_name in expect.items():
            assert path in by_path, f"{path} missing"
            assert types[_numeric(by_path[path]["typeDefinition"])] == type_name, path
    assert checked >= 2 * (1 + 1 + 6 + 6 + 6 + 1 + 1)


# --------------------------------------------------------------------------- values


async def _stopped(cell: Cell) -> None:
    """The still robot's program stopped and its joints at rest (two frames alike)."""
    async with httpx.AsyncClient(base_url=cell.control_url) as api:
        answer = await api.post("/program", json={"running": False})
        assert answer.status_code == 200, answer.text
    hub = cell.running.service.robots["still"].frames
    seen: list[tuple[float, ...]] = []

    def at_rest() -> bool:
        latest = hub.latest
        if latest is None:
            return False
        seen.append(latest[2].joint_velocity)
        return len(seen) > 20 and all(abs(v) < 1e-6 for v in seen[-1]) and seen[-1] == seen[-20]

    await eventually(at_rest)


async def test_values_are_the_frame(cell: Cell) -> None:
    """Each axis's ActualPosition (and the motors' temperatures, the layout's variables) equal
    the frame the service has, with their units; the nameplate is the robot's identity."""
    await _stopped(cell)
    robot = cell.running.service.robots["still"]
    axes = "MotionDevices.still.Axes"
    trains = "MotionDevices.still.PowerTrains"
    nodes = [f"{axes}.Axis{j}.ParameterSet.ActualPosition" for j in range(1, 7)]
    nodes += [f"{trains}.PowerTrain{j}.Motor1.ParameterSet.MotorTemperature" for j in range(1, 7)]
    nodes += [f"Frame.joint_position.{j}" for j in range(6)]
    nodes += [
        "Frame.robot_state",
        "Frame.robot_state.ValueAsText",
        f"{axes}.Axis1.ParameterSet.ActualPosition.EngineeringUnits",
        f"{axes}.Axis3.ParameterSet.ActualPosition.EURange",
        "MotionDevices.still.Manufacturer",
        "MotionDevices.still.SerialNumber",
        "Controllers.still.SoftwareRevision",
    ]

    async def read() -> list[dict[str, Any]]:
        answer: list[dict[str, Any]] = await cell.peer.request(
            "read", name="operator", nodes=[cell.node("still", n) for n in nodes]
        )
        return answer

    values = await read()
    latest = robot.frames.latest
    assert latest is not None
    frame = latest[2]
    assert all(v["status"] == "Good" for v in values), values
    for joint in range(6):
        assert values[joint]["value"] == pytest.approx(frame.joint_position[joint], abs=1e-4)
        assert values[joint]["dataType"] == "Double"
        temperature = values[6 + joint]["value"]
        assert temperature == pytest.approx(frame.joint_motor_temperature[joint], abs=0.05)
        assert values[12 + joint]["value"] == pytest.approx(frame.joint_position[joint], abs=1e-4)
    state, text, units, span, maker, serial, revision = (v["value"] for v in values[18:])
    assert state == frame.robot_state
    assert text == "STANDALONE_STANDBY" or text.startswith(("STANDALONE", "COLLABORATIVE"))
    assert units["unitId"] == unit_for("degree").unit_id
    assert (span["low"], span["high"]) == (-160.0, 160.0)  # the M1013's J3 limit (arms.py)
    assert maker == "Doosan Robotics"
    assert robot.identity is not None
    assert serial == str(robot.identity.serial_number)
    version = frame.controller_version
    assert revision == f"{version.major}.{version.minor}.{version.patch}"


async def test_updates_come_at_the_monitoring_rate(cell: Cell) -> None:
    """A subscription to a moving axis gets about one update per monitoring period (10 Hz),
    each a newer frame: counted over a window, with a tolerance no load can break."""
    node = cell.node("moving", "MotionDevices.moving.Axes.Axis1.ParameterSet.ActualPosition")
    await cell.peer.request(
        "monitor", name="anonymous", key="rate", nodes=[node], samplingMs=100, publishingMs=100
    )
    loop = asyncio.get_running_loop()
    await cell.peer.request("take", key="rate")
    started = loop.time()
    updates: list[dict[str, Any]] = []

    async def enough() -> bool:
        updates.extend(await cell.peer.request("take", key="rate"))
        return loop.time() - started >= 4.0

    while not await enough():  # noqa: ASYNC110 - polls the client's notifications
        await asyncio.sleep(0.2)
    window_s = loop.time() - started  # (a poll of the client's notifications, not a wait)
    await cell.peer.request("unmonitor", key="rate")
    good = [u for u in updates if u["status"] == "Good"]
    rate_hz = len(good) / window_s
    assert 3.0 <= rate_hz <= 15.0, (rate_hz, len(good), window_s)
    stamps = [u["sourceTimestamp"] + u["sourcePicoseconds"] / 1e9 for u in good]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)


async def test_emergency_stop_reaches_the_safety_state(cell: Cell) -> None:
    node = cell.node("still", "SafetyStates.still.ParameterSet.EmergencyStop")
    async with httpx.AsyncClient(base_url=cell.control_url) as api:
        assert (await api.post("/estop", json={})).status_code == 200
        try:

            async def stopped() -> bool:
                values = await cell.peer.request("read", name="anonymous", nodes=[node])
                return bool(values[0]["value"] is True)

            await _eventually_async(stopped)
        finally:
            assert (await api.post("/reset", json={})).status_code == 200

    async def released() -> bool:
        values = await cell.peer.request("read", name="anonymous", nodes=[node])
        return bool(values[0]["value"] is False)

    await _eventually_async(released)


async def _eventually_async(check: Any) -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + 60
    while not await check():
        assert loop.time() < end, "condition not reached in time"
        await asyncio.sleep(0.1)


# --------------------------------------------------------------------------- users and writes


async def _audit(cell: Cell) -> list[dict[str, Any]]:
    token = await cell.running.login(OPERATOR)
    async with cell.running.client(token) as client:
        answer = await client.get("/api/v1/audit", params={"limit": 20})
    assert answer.status_code == 200, answer.text
    rows: list[dict[str, Any]] = answer.json()["items"]
    return rows


DO_3 = "Command.controlbox_do.2"


async def test_wrong_password_is_refused(cell: Cell) -> None:
    with pytest.raises(PeerError, match=r"BadUserAccessDenied|BadIdentityTokenRejected"):
        await cell.peer.connect("intruder", cell.endpoint, user=(OPERATOR[0], "not-the-password"))


async def test_viewer_and_anonymous_cannot_write(cell: Cell) -> None:
    item = {"node": cell.node("still", DO_3), "dataType": "Boolean", "value": True}
    for session in ("viewer", "anonymous"):
        assert await cell.peer.request("write", name=session, items=[item]) == [
            "BadUserAccessDenied"
        ]
    rows = await _audit(cell)
    assert rows[0]["outcome"] == "unauthorized" and rows[1]["outcome"] == "forbidden", rows[:2]
    assert rows[1]["user"] == VIEWER[0] and "OPC UA" in rows[1]["client"]


async def test_write_without_control_is_refused(cell: Cell) -> None:
    item = {"node": cell.node("still", DO_3), "dataType": "Boolean", "value": True}
    assert await cell.peer.request("write", name="operator", items=[item]) == ["BadInvalidState"]
    row = (await _audit(cell))[0]
    assert (row["user"], row["outcome"]) == (OPERATOR[0], "refused"), row


async def test_confirmed_write_changes_the_robots_output(cell: Cell) -> None:
    """TakeControl, a write answered Good once the robot's frame shows it, the robot's output
    on (its control API), the audit row with the OPC UA user and session; ReleaseControl."""
    robot_object = cell.node("still", "").rstrip(".")
    take = await cell.peer.request(
        "call", name="operator", object=robot_object, method=cell.node("still", "TakeControl")
    )
    assert take == {"status": "Good", "outputs": [OPERATOR[0]]}
    try:
        item = {"node": cell.node("still", DO_3), "dataType": "Boolean", "value": True}
        assert await cell.peer.request("write", name="operator", items=[item]) == ["Good"]
        async with httpx.AsyncClient(base_url=cell.control_url) as api:
            status = (await api.get("/status")).json()
        assert status["plc_command"]["controlbox_do"][2] is True
        assert status["frame"]["controlbox_do"][2] is True

        # The server publishes the newest frame at its next monitoring tick (10 Hz).
        async def shown() -> bool:
            values = await cell.peer.request(
                "read", name="anonymous", nodes=[cell.node("still", "Frame.controlbox_do.2")]
            )
            return values[0]["value"] is True

        await _eventually_async(shown)
        row = (await _audit(cell))[0]
        assert (row["user"], row["outcome"], row["action"]) == (OPERATOR[0], "confirmed", "write")
        assert row["fields"] == ["controlbox_do.2"]
        assert "OPC UA" in row["client"] and "session" in row["client"], row
        assert row["origin"] == "OPC UA Write"
    finally:
        release = await cell.peer.request(
            "call",
            name="operator",
            object=robot_object,
            method=cell.node("still", "ReleaseControl"),
        )
    assert release == {"status": "Good", "outputs": [""]}


# --------------------------------------------------------------------------- security


async def test_none_refused_on_a_non_loopback_bind(cell: Cell, tmp_path: Path) -> None:
    """Bound to 0.0.0.0 without --opcua-allow-no-security the server offers Sign and
    SignAndEncrypt only: a client asking for None is refused, SignAndEncrypt works; and with
    view_requires_login no anonymous session is accepted."""
    service = cell.running.service
    port = free_tcp_port("0.0.0.0")
    settings = cell.running.settings.replace(
        opcua_url=f"opc.tcp://0.0.0.0:{port}", view_requires_login=True
    )
    state_dir = tmp_path / "state"
    trust(cell.certificate[0], settings.opcua.opcua_trusted_dir(state_dir))
    feed = ServiceFeed(service.robots, service.users, settings.web, asyncio.get_running_loop())
    server = OpcUaServer(settings.opcua, state_dir, feed)
    await server.start()
    endpoint = f"opc.tcp://{cell.running.settings.web.host}:{port}"
    try:
        with pytest.raises(PeerError):
            await cell.peer.connect("open", endpoint, user=OPERATOR)
        with pytest.raises(PeerError):
            await cell.peer.connect(
                "anonymous-2", endpoint, mode="SignAndEncrypt", certificate=cell.certificate
            )
        await cell.peer.connect(
            "secure", endpoint, mode="SignAndEncrypt", user=OPERATOR, certificate=cell.certificate
        )
        values = await cell.peer.request(
            "read", name="secure", nodes=[cell.node("still", "Frame.robot_state")]
        )
        assert values[0]["status"] in ("Good", "BadWaitingForInitialData")
        await cell.peer.request("disconnect", name="secure")
    finally:
        await server.stop()
    assert (state_dir / "opcua" / "pki" / "own" / "cert.der").is_file()


async def test_an_untrusted_client_certificate_is_refused(cell: Cell, tmp_path: Path) -> None:
    stranger = client_certificate(tmp_path / "stranger")
    with pytest.raises(PeerError):
        await cell.peer.connect(
            "stranger", cell.endpoint, mode="SignAndEncrypt", user=OPERATOR, certificate=stranger
        )
    rejected = cell.state_dir / "opcua" / "pki" / "rejected"
    assert any(rejected.iterdir()), "the refused certificate is kept for an administrator"


# --------------------------------------------------------------------------- the link


async def test_values_go_bad_while_the_robot_is_away(cell: Cell) -> None:
    """The moving robot's emulator stops: its values go BadCommunicationError; it starts again
    on the same address: Good again."""
    node = cell.node("moving", "MotionDevices.moving.Axes.Axis2.ParameterSet.ActualPosition")
    await cell.peer.request(
        "monitor", name="anonymous", key="link", nodes=[node], samplingMs=100, publishingMs=100
    )
    seen: list[str] = []

    async def saw(status: str) -> bool:
        seen.extend(u["status"] for u in await cell.peer.request("take", key="link"))
        return status in seen

    await _eventually_async(lambda: saw("Good"))
    settings = cell.moving_target.settings
    port = cell.moving_target.tcp_port
    await cell.moving_target.stop()
    await _eventually_async(lambda: saw("BadCommunicationError"))
    seen.clear()
    restarted = Target(
        TargetSettings(host=settings.host, tcp_port=port, identity=settings.identity), cell.moving
    )
    await restarted.start()
    cell.moving_target = restarted
    await _eventually_async(lambda: saw("Good"))
    await cell.peer.request("unmonitor", key="link")
