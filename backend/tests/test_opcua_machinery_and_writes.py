"""The OPC UA server without writes, its BuildInfo and data types, and the Machinery building
blocks (issue 37, items 4–6), seen as a plant client sees them: asyncua's client (its own
encoding and decoding, none of the server's code), reading, writing, browsing and calling.

One cell for the module: a simulated M1013 ("still") with its control API, the service holding
it with OPC UA on its own loopback address and ``opcua_writes`` off (the default), an anonymous
session over None and the operator's over SignAndEncrypt. The expected values come from the
specifications' own files where they can (the NodeSet files, npm's Machinery NodeSet) and from
docs/api.md's tables, never from the server's modules.
"""

from __future__ import annotations

import contextlib
import xml.etree.ElementTree as ET
from collections.abc import AsyncIterator
from dataclasses import dataclass
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any

import httpx
import pytest
import pytest_asyncio
from asyncua import Client, ua

from cobot_hmi import __version__
from cobot_hmi.emulator.control_api import ControlApiServer, create_control_app
from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from conftest import _next_host as next_host
from conftest import free_tcp_port
from emulator_harness import FAST_TIMINGS
from opcua_support import (
    ANSWER_S,
    CLIENT_URI,
    PEERS,
    client_certificate,
    listening_port,
    trust,
)
from service_support import OPERATOR, Running, cell_settings, running_service
from waiting import eventually_async

pytestmark = [pytest.mark.timeout(300), pytest.mark.asyncio(loop_scope="module")]

NODESETS = Path(__file__).parents[1] / "src/cobot_hmi/opcua/nodesets"
MACHINERY_NODESET = (
    PEERS / "node_modules/node-opcua-nodesets/nodesets/Opc.Ua.Machinery.NodeSet2.xml"
)
UA_NS = "{http://opcfoundation.org/UA/2011/03/UANodeSet.xsd}"
DI_URI = "http://opcfoundation.org/UA/DI/"
MACHINERY_URI = "http://opcfoundation.org/UA/Machinery/"
ROBOT = "still"
DO_3 = "Command.controlbox_do.2"

# docs/api.md, "OPC UA: the Machinery building blocks": the robot state (layout.py's enum, by
# value) → (MachineryItemState, MachineryOperationMode).
STATE_MAPPING: dict[int, tuple[str, str]] = {
    0: ("OutOfService", "None"),  # EMERGENCY_STOP
    1: ("NotAvailable", "None"),  # INITIALIZING
    2: ("OutOfService", "None"),  # SAFE_OFF
    3: ("OutOfService", "None"),  # INTERRUPTED
    4: ("NotExecuting", "Setup"),  # MANUAL_STANDBY
    5: ("Executing", "Setup"),  # MANUAL_JOGGING
    6: ("Executing", "Setup"),  # MANUAL_HANDGUIDING
    7: ("OutOfService", "Maintenance"),  # RECOVERY_STANDBY
    8: ("OutOfService", "Maintenance"),  # RECOVERY_JOGGING
    9: ("OutOfService", "Maintenance"),  # BACKDRIVE_HOLD
    10: ("OutOfService", "Maintenance"),  # BACKDRIVE_RELEASE
    11: ("OutOfService", "Maintenance"),  # BACKDRIVE_RELEASE_BY_COCKPIT
    12: ("OutOfService", "Maintenance"),  # RECOVERY_HANDGUIDING
    13: ("NotExecuting", "Processing"),  # STANDALONE_STANDBY
    14: ("Executing", "Processing"),  # STANDALONE_RUNNING
    15: ("NotExecuting", "Processing"),  # COLLABORATIVE_STANDBY
    16: ("Executing", "Processing"),  # COLLABORATIVE_RUNNING
    17: ("Executing", "Processing"),  # HIGH_PRIORITY_RUNNING
    18: ("Executing", "Setup"),  # AUTO_MEASURE
    19: ("NotExecuting", "Processing"),  # HANDGUIDING_CONTROL_STANDBY
    20: ("Executing", "Processing"),  # HANDGUIDING_CONTROL_RUNNING
    99: ("NotAvailable", "None"),  # outside the table
}


@dataclass
class Cell:
    running: Running
    robot: SimulatedRobot
    target: Target
    control_url: str
    endpoint: str
    anonymous: Client
    operator: Client
    namespaces: list[str]

    def ns(self, uri: str) -> int:
        return self.namespaces.index(uri)

    def node(self, path: str = "") -> ua.NodeId:
        """The robot's node by its browse path (``Command.controlbox_do.2``; "" its object)."""
        text = f"{ROBOT}.{path}" if path else ROBOT
        return ua.NodeId(text, self.ns("urn:cobot-hmi:robot:" + ROBOT))


async def _client(endpoint: str, **login: Any) -> Client:
    # asyncua's watchdog reads the server's state every second and tears the session down when
    # one answer is late: on a busy machine that was the test's failure, not the server's.
    client = Client(endpoint, timeout=ANSWER_S, watchdog_intervall=ANSWER_S)
    client.application_uri = CLIENT_URI
    if "certificate" in login:
        certificate, key = login["certificate"]
        await client.set_security_string(f"Basic256Sha256,SignAndEncrypt,{certificate},{key}")
    if "user" in login:
        client.set_user(login["user"][0])
        client.set_password(login["user"][1])
    await client.connect()
    return client


@contextlib.asynccontextmanager
async def _cell(state_dir: Path) -> AsyncIterator[Cell]:
    plc_host, robot_host = next_host(), next_host()
    robot = SimulatedRobot(RobotSettings(timings=FAST_TIMINGS))
    target = Target(TargetSettings(host=robot_host, tcp_port=0), robot)
    await target.start()
    control = ControlApiServer(
        create_control_app(robot, target), robot_host, free_tcp_port(robot_host)
    )
    await control.start()
    endpoint = f"opc.tcp://{plc_host}:{listening_port(plc_host)}"
    settings = cell_settings(
        [(ROBOT, robot_host, target.tcp_port)],
        plc_host,
        state_dir,
        opcua_url=endpoint,
        opcua_writes=False,
    )
    cert_path, key_path = client_certificate(state_dir / "client")
    trust(cert_path, settings.opcua.opcua_trusted_dir(state_dir))
    # asyncua's client reads a key as PEM only when its file is named so.
    certificate = (cert_path, key_path.rename(key_path.with_suffix(".key.pem")))
    cell: Cell | None = None
    try:
        async with running_service(settings) as running:
            anonymous = await _client(endpoint)
            operator = await _client(endpoint, user=OPERATOR, certificate=certificate)
            namespaces = await anonymous.get_namespace_array()
            cell = Cell(
                running,
                robot,
                target,
                f"http://{robot_host}:{control.port}",
                endpoint,
                anonymous,
                operator,
                namespaces,
            )
            try:
                yield cell
            finally:
                await anonymous.disconnect()
                await operator.disconnect()
    finally:
        await control.stop()
        await (cell.target if cell is not None else target).stop()


@pytest_asyncio.fixture(scope="module", loop_scope="module")
async def cell(tmp_path_factory: pytest.TempPathFactory) -> AsyncIterator[Cell]:
    async with _cell(tmp_path_factory.mktemp("opcua-machinery")) as running:
        yield running


async def _read(client: Client, nodes: list[ua.NodeId], attribute: Any = None) -> list[Any]:
    """Each node's attribute (the Value unless named) as the server answers: its DataValue."""
    attribute = attribute if attribute is not None else ua.AttributeIds.Value
    answers: list[ua.DataValue] = []
    for start in range(0, len(nodes), 500):
        chunk = nodes[start : start + 500]
        parameters = ua.ReadParameters()
        parameters.NodesToRead = [ua.ReadValueId(NodeId=n, AttributeId=attribute) for n in chunk]
        answers += await client.uaclient.read(parameters)
    return answers


async def _children(client: Client, node: ua.NodeId, reference: int) -> list[Any]:
    """The forward references of ``reference`` (and its subtypes) from ``node``."""
    result: list[Any] = await client.get_node(node).get_references(
        refs=reference, direction=ua.BrowseDirection.Forward, includesubtypes=True
    )
    return result


# --------------------------------------------------------------------------- item 4: no writes


async def test_a_read_only_variable_answers_bad_not_writable(cell: Cell) -> None:
    """With writes off, the operator's write to a command output (and to a frame value) is
    BadNotWritable (OPC 10000-4: the AccessLevel does not allow writing), not
    BadUserAccessDenied; the AccessLevel says so, and the robot's command is unchanged. What
    does not exist is answered so, not BadUserAccessDenied either."""
    value = ua.DataValue(ua.Variant(True, ua.VariantType.Boolean))
    items = [
        ua.WriteValue(NodeId=cell.node(path), AttributeId=ua.AttributeIds.Value, Value=value)
        for path in (DO_3, "Frame.controlbox_do.2", "NoSuchNode", "Status")
    ]
    name = ua.DataValue(ua.Variant(ua.LocalizedText("DO 3"), ua.VariantType.LocalizedText))
    attribute = ua.AttributeIds.DisplayName
    items.append(ua.WriteValue(NodeId=cell.node(DO_3), AttributeId=attribute, Value=name))
    statuses = await cell.operator.uaclient.write(ua.WriteParameters(NodesToWrite=items))
    assert [s.name for s in statuses] == [
        "BadNotWritable",
        "BadNotWritable",
        "BadNodeIdUnknown",  # no such node
        "BadAttributeIdInvalid",  # an object has no Value
        "BadNotWritable",  # no attribute but the Value is ever writable
    ]
    (level,) = await _read(cell.operator, [cell.node(DO_3)], ua.AttributeIds.AccessLevel)
    assert not level.Value.Value & ua.AccessLevel.CurrentWrite.mask
    assert cell.running.service.robots[ROBOT].link.command.controlbox_do[2] is False


async def test_without_writes_no_session_can_take_control(cell: Cell) -> None:
    """With writes off the robot's object has no TakeControl nor ReleaseControl; calling the
    method's NodeId anyway is refused, nobody holds control, and the panel's operator can take
    it over HTTP (an OPC UA session that cannot write never locks them out)."""
    robot_object = cell.node()
    methods = await _children(cell.operator, robot_object, ua.ObjectIds.HasComponent)
    names = {m.BrowseName.Name for m in methods if m.NodeClass == ua.NodeClass.Method}
    assert not names & {"TakeControl", "ReleaseControl"}, names
    request = ua.CallMethodRequest(ObjectId=robot_object, MethodId=cell.node("TakeControl"))
    (result,) = await cell.operator.uaclient.call([request])
    assert not result.StatusCode.is_good(), result.StatusCode
    robot = cell.running.service.robots[ROBOT]
    assert robot.control.holder is None
    token = await cell.running.login(OPERATOR)
    async with cell.running.client(token) as api:
        taken = await api.post(f"/api/v1/robots/{ROBOT}/control/take")
        assert taken.status_code == 200, taken.text
        released = await api.post(f"/api/v1/robots/{ROBOT}/control/release")
        assert released.status_code == 200, released.text


# --------------------------------------------------------------------------- item 5: identity


def _installed_at() -> datetime:
    """When pip installed the distribution: its METADATA file's time."""
    files = [f for f in metadata.distribution("cobot-hmi").files or () if f.name == "METADATA"]
    return datetime.fromtimestamp(Path(str(files[0].locate())).stat().st_mtime, UTC)


async def test_build_info_names_the_product(cell: Cell) -> None:
    """BuildInfo (OPC 10000-5 §12.4), whole and member by member, is cobot-hmi's: its name, the
    installed distribution's version and the time it was installed; every endpoint and
    FindServers describe a Server, not a ClientAndServer."""
    assert metadata.version("cobot-hmi") == __version__
    installed = _installed_at()
    base = ua.ObjectIds
    status, info, *members = await _read(
        cell.anonymous,
        [
            ua.NodeId(n)
            for n in (
                base.Server_ServerStatus,
                base.Server_ServerStatus_BuildInfo,
                base.Server_ServerStatus_BuildInfo_ProductUri,
                base.Server_ServerStatus_BuildInfo_ManufacturerName,
                base.Server_ServerStatus_BuildInfo_ProductName,
                base.Server_ServerStatus_BuildInfo_SoftwareVersion,
                base.Server_ServerStatus_BuildInfo_BuildNumber,
                base.Server_ServerStatus_BuildInfo_BuildDate,
            )
        ],
    )
    expected = ["urn:cobot-hmi", "The cobot-hmi project", "cobot-hmi", __version__, __version__]
    for build in (status.Value.Value.BuildInfo, info.Value.Value):
        assert [
            build.ProductUri,
            build.ManufacturerName,
            build.ProductName,
            build.SoftwareVersion,
            build.BuildNumber,
        ] == expected
        assert abs((build.BuildDate.replace(tzinfo=UTC) - installed).total_seconds()) < 1e-3
    assert [m.Value.Value for m in members[:5]] == expected
    assert abs((members[5].Value.Value.replace(tzinfo=UTC) - installed).total_seconds()) < 1e-3
    started = status.Value.Value.StartTime.replace(tzinfo=UTC)
    assert installed < started, "the build date is the installation's, not the start's"
    endpoints = await cell.anonymous.get_endpoints()
    assert endpoints
    for endpoint in endpoints:
        assert endpoint.Server.ApplicationType == ua.ApplicationType.Server
        assert endpoint.Server.ApplicationName.Text == "cobot-hmi"
    servers = await cell.anonymous.find_servers()
    assert [s.ApplicationType for s in servers] == [ua.ApplicationType.Server]


def _declared_data_types(path: Path, namespaces: list[str]) -> dict[ua.NodeId, ua.NodeId]:
    """Every variable and variable type of a NodeSet file → its DataType as the file gives it
    (an alias resolved; no attribute: the schema's default, i=24), in the server's indices."""
    root = ET.parse(path).getroot()
    uris = ["http://opcfoundation.org/UA/"]
    uris += [u.text or "" for u in root.find(f"{UA_NS}NamespaceUris") or []]
    aliases = {str(a.get("Alias")): str(a.text) for a in root.find(f"{UA_NS}Aliases") or []}

    def server_id(text: str) -> ua.NodeId:
        text = aliases.get(text, text)
        if text.startswith("ns="):
            index, identifier = text.split(";", 1)
            text = f"ns={namespaces.index(uris[int(index[3:])])};{identifier}"
        return ua.NodeId.from_string(text)

    declared = {}
    for element in root:
        if element.tag in (f"{UA_NS}UAVariable", f"{UA_NS}UAVariableType"):
            declared[server_id(str(element.get("NodeId")))] = server_id(
                element.get("DataType") or "i=24"
            )
    return declared


async def test_companion_variables_have_the_nodesets_data_types(cell: Cell) -> None:
    """Every variable and variable type the four NodeSet files declare has, over the wire, the
    DataType its file gives (none Null): DI's UIElementType, its two UIElements and
    <ParameterIdentifier> leave it to the schema's default, BaseDataType."""
    di = cell.ns(DI_URI)
    defaulted = [ua.NodeId(i, di) for i in (6017, 6246, 6242, 6243)]
    answers = await _read(cell.anonymous, defaulted, ua.AttributeIds.DataType)
    assert [a.Value.Value for a in answers] == [ua.NodeId(ua.ObjectIds.BaseDataType)] * 4
    for path in sorted(NODESETS.glob("*.NodeSet2.xml")):
        declared = _declared_data_types(path, cell.namespaces)
        nodes = list(declared)
        answers = await _read(cell.anonymous, nodes, ua.AttributeIds.DataType)
        wrong = {
            node.to_string(): (answer.Value.Value if answer.Value else answer.StatusCode)
            for node, answer in zip(nodes, answers, strict=True)
            if answer.Value is None or answer.Value.Value != declared[node]
        }
        assert not wrong, f"{path.name}: {wrong}"


# --------------------------------------------------------------------------- item 6: Machinery


def _machinery_model() -> tuple[dict[str, int], dict[int, set[str]], dict[str, int]]:
    """From npm's Machinery NodeSet (not the server's copy): type browse name → numeric id;
    type id → its mandatory members' browse names; state name → the state's numeric id, for
    the two state machine types."""
    root = ET.parse(MACHINERY_NODESET).getroot()
    elements = [e for e in root if e.get("NodeId", "").startswith("ns=1;")]

    def numeric(node_id: str) -> int:
        return int(node_id.split(";i=", 1)[1])

    def name(element: ET.Element) -> str:
        return str(element.get("BrowseName")).split(":", 1)[-1]

    def references(element: ET.Element) -> list[tuple[str, str]]:
        found = element.find(f"{UA_NS}References")
        return [(str(r.get("ReferenceType")), r.text or "") for r in found or []]

    types = {name(e): numeric(str(e.get("NodeId"))) for e in elements if e.tag.endswith("Type")}
    mandatory: dict[int, set[str]] = {}
    states: dict[str, int] = {}
    for element in elements:
        parent = element.get("ParentNodeId", "")
        if not parent.startswith("ns=1;"):
            continue
        kinds = references(element)
        if ("HasModellingRule", "i=78") in kinds:
            mandatory.setdefault(numeric(parent), set()).add(name(element))
        if ("HasTypeDefinition", "i=2307") in kinds and numeric(parent) in (
            types["MachineryItemState_StateMachineType"],
            types["MachineryOperationModeStateMachineType"],
        ):
            states[name(element)] = numeric(str(element.get("NodeId")))
    return types, mandatory, states


async def test_machines_folder_holds_the_robot_with_its_identification(cell: Cell) -> None:
    """Objects/Machines (OPC 40001-1 §9) organizes the robot's MotionDeviceSystem; it has an
    Identification add-in of MachineIdentificationType with the type's mandatory members and
    the robot's nameplate, and MachineryBuildingBlocks with the identification and the two
    state machines of the NodeSet's types."""
    types, mandatory, _ = _machinery_model()
    machinery = cell.ns(MACHINERY_URI)
    machines = await _children(cell.anonymous, ua.NodeId(1001, machinery), ua.ObjectIds.Organizes)
    assert cell.node() in [m.NodeId for m in machines]
    add_ins = await _children(cell.anonymous, cell.node(), ua.ObjectIds.HasAddIn)
    identification = next(a for a in add_ins if a.BrowseName.Name == "Identification")
    assert identification.BrowseName.NamespaceIndex == cell.ns(DI_URI)
    machine_type = types["MachineIdentificationType"]
    assert identification.TypeDefinition == ua.NodeId(machine_type, machinery)
    members = await _children(cell.anonymous, identification.NodeId, ua.ObjectIds.HasProperty)
    by_name = {m.BrowseName.Name: m.NodeId for m in members}
    required = mandatory[machine_type] | mandatory[types["MachineryItemIdentificationType"]]
    assert required == {"ProductInstanceUri", "Manufacturer", "SerialNumber"}
    assert required <= set(by_name), (required, set(by_name))
    identity = cell.running.service.robots[ROBOT].identity
    assert identity is not None
    names = ("Manufacturer", "SerialNumber", "ProductInstanceUri", "Model", "ProductCode")
    values = await _read(cell.anonymous, [by_name[n] for n in names])
    assert all(v.StatusCode.is_good() for v in values), values
    maker, serial, uri, model, code = (v.Value.Value for v in values)
    assert maker.Text == "Doosan Robotics"
    assert (serial, model.Text, code) == (
        str(identity.serial_number),
        identity.product_name,
        str(identity.product_code),
    )
    assert uri.endswith(f"/{identity.product_code}/{identity.serial_number}") and "://" in uri
    blocks = await _children(cell.anonymous, cell.node(), ua.ObjectIds.HasComponent)
    folder = next(b for b in blocks if b.BrowseName.Name == "MachineryBuildingBlocks")
    assert folder.BrowseName.NamespaceIndex == machinery
    in_folder = await _children(cell.anonymous, folder.NodeId, ua.ObjectIds.HasAddIn)
    found = {b.BrowseName.Name: b for b in in_folder}
    assert found["Identification"].NodeId == identification.NodeId
    for block, type_name in (
        ("MachineryItemState", "MachineryItemState_StateMachineType"),
        ("MachineryOperationMode", "MachineryOperationModeStateMachineType"),
    ):
        assert found[block].TypeDefinition == ua.NodeId(types[type_name], machinery)


async def _machine_states(cell: Cell) -> list[tuple[str, ua.NodeId, bool]]:
    """(CurrentState, its Id, both Good) of MachineryItemState and MachineryOperationMode."""
    base = "MachineryBuildingBlocks"
    nodes = []
    for machine in ("MachineryItemState", "MachineryOperationMode"):
        nodes += [
            cell.node(f"{base}.{machine}.CurrentState"),
            cell.node(f"{base}.{machine}.CurrentState.Id"),
        ]
    values = await _read(cell.anonymous, nodes)
    return [
        (
            values[i].Value.Value.Text if values[i].Value.Value else "",
            values[i + 1].Value.Value,
            values[i].StatusCode.is_good() and values[i + 1].StatusCode.is_good(),
        )
        for i in (0, 2)
    ]


async def _shows(cell: Cell, item: str, mode: str) -> None:
    """Until both state machines show ``item`` and ``mode``, their Ids the NodeSet's states."""
    _, _, states = _machinery_model()
    machinery = cell.ns(MACHINERY_URI)
    want = [(item, ua.NodeId(states[item], machinery), True)]
    want.append((mode, ua.NodeId(states[mode], machinery), True))
    seen: list[Any] = []

    async def shown() -> bool:
        seen[:] = await _machine_states(cell)
        return seen == want

    try:
        await eventually_async(shown)
    except AssertionError:
        raise AssertionError(f"wanted {want}, the server shows {seen}") from None


async def test_machinery_states_follow_the_robot_state(cell: Cell) -> None:
    """Each robot state (forced on the emulator, seen in the service's frame) gives the
    MachineryItemState and MachineryOperationMode docs/api.md's table says, with the Id of
    that state in the Machinery NodeSet."""
    frames = cell.running.service.robots[ROBOT].frames
    async with httpx.AsyncClient(base_url=cell.control_url) as api:
        try:
            for state, (item, mode) in STATE_MAPPING.items():
                answer = await api.post("/state", json={"robot_state": state})
                assert answer.status_code == 200, answer.text

                async def in_frame(state: int = state) -> bool:
                    latest = frames.latest
                    return latest is not None and latest[2].robot_state == state

                await eventually_async(in_frame)
                await _shows(cell, item, mode)
        finally:
            assert (await api.post("/reset", json={})).status_code == 200


async def test_machine_not_available_while_the_link_is_down(cell: Cell) -> None:
    """The emulator stops: MachineryItemState NotAvailable and the mode None, Good (the state
    of the machine is known: it is not available); it starts again on the same address: the
    robot's state again."""
    robot = cell.running.service.robots[ROBOT]
    target = cell.target
    settings, port = target.settings, target.tcp_port
    await target.stop()
    await _shows(cell, "NotAvailable", "None")
    restarted = Target(
        TargetSettings(host=settings.host, tcp_port=port, identity=settings.identity), cell.robot
    )
    await restarted.start()
    cell.target = restarted
    assert await robot.link.wait_connected(ANSWER_S)

    async def available() -> bool:
        item = (await _machine_states(cell))[0]
        return item[0] != "NotAvailable" and item[2]

    await eventually_async(available, timeout_s=ANSWER_S)
