"""Layer: service (OPC UA). The companion specifications' models: loaded, and the types named.

The server imports the OPC Foundation's own NodeSet2 files (``nodesets/``: DI 1.04.0, IA
1.01.4, Robotics 1.02, Machinery 1.04.1; their README says where each comes from and why these
versions), so every type, reference type and enumeration has the NodeId and browse name the
specifications give it. This module names the ones the robots' instances use, by model URI and
numeric id (``TypeRef``), and resolves them to the namespace indices of the running server;
``load`` checks each against the imported model (its browse name), so a file and the names here
can never disagree unnoticed.

A variable or variable type whose NodeSet element has no ``DataType`` attribute has the
schema's default, ``i=24`` (BaseDataType, UANodeSet.xsd); asyncua's importer leaves it Null
(DI's ``UIElementType``, ``UIElement`` twice, ``<ParameterIdentifier>``), so ``load`` gives
those nodes the NodeSet's own value after the import.
"""

from __future__ import annotations

import logging
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from asyncua import Server, ua

NODESET_DIR: Final = Path(__file__).parent / "nodesets"

DI_URI: Final = "http://opcfoundation.org/UA/DI/"
IA_URI: Final = "http://opcfoundation.org/UA/IA/"
ROBOTICS_URI: Final = "http://opcfoundation.org/UA/Robotics/"
MACHINERY_URI: Final = "http://opcfoundation.org/UA/Machinery/"

NODESETS: Final = (
    ("Opc.Ua.Di.NodeSet2.xml", DI_URI),
    ("Opc.Ua.IA.NodeSet2.xml", IA_URI),
    ("Opc.Ua.Robotics.NodeSet2.xml", ROBOTICS_URI),
    ("Opc.Ua.Machinery.NodeSet2.xml", MACHINERY_URI),
)
"""In import order: each model after the ones it requires (Machinery last, so the namespace
indices of the models before it stay what they were before it came)."""
_UA_NODESET: Final = "{http://opcfoundation.org/UA/2011/03/UANodeSet.xsd}"
_BASE_DATA_TYPE: Final = ua.NodeId(ua.ObjectIds.BaseDataType)


@dataclass(frozen=True, slots=True)
class TypeRef:
    """A node of a companion specification: its model, numeric id and browse name."""

    uri: str
    identifier: int
    name: str


# Devices (OPC 10000-100).
DEVICE_SET: Final = TypeRef(DI_URI, 5001, "DeviceSet")
SOFTWARE_TYPE: Final = TypeRef(DI_URI, 15106, "SoftwareType")
# Robotics (OPC 40010-1).
MOTION_DEVICE_SYSTEM_TYPE: Final = TypeRef(ROBOTICS_URI, 1002, "MotionDeviceSystemType")
MOTION_DEVICE_TYPE: Final = TypeRef(ROBOTICS_URI, 1004, "MotionDeviceType")
AXIS_TYPE: Final = TypeRef(ROBOTICS_URI, 16601, "AxisType")
POWER_TRAIN_TYPE: Final = TypeRef(ROBOTICS_URI, 16794, "PowerTrainType")
MOTOR_TYPE: Final = TypeRef(ROBOTICS_URI, 1019, "MotorType")
CONTROLLER_TYPE: Final = TypeRef(ROBOTICS_URI, 1003, "ControllerType")
SAFETY_STATE_TYPE: Final = TypeRef(ROBOTICS_URI, 1013, "SafetyStateType")
TASK_CONTROL_TYPE: Final = TypeRef(ROBOTICS_URI, 1011, "TaskControlType")
CONTROLS: Final = TypeRef(ROBOTICS_URI, 4002, "Controls")
HAS_SAFETY_STATES: Final = TypeRef(ROBOTICS_URI, 18182, "HasSafetyStates")
MOVES: Final = TypeRef(ROBOTICS_URI, 18178, "Moves")
REQUIRES: Final = TypeRef(ROBOTICS_URI, 18179, "Requires")
AXIS_MOTION_PROFILE: Final = TypeRef(ROBOTICS_URI, 3008, "AxisMotionProfileEnumeration")
OPERATIONAL_MODE: Final = TypeRef(ROBOTICS_URI, 3006, "OperationalModeEnumeration")
MOTION_DEVICE_CATEGORY: Final = TypeRef(ROBOTICS_URI, 18193, "MotionDeviceCategoryEnumeration")
# Machinery (OPC 40001-1): the entry point, the nameplate, the two state machines and their states.
MACHINES: Final = TypeRef(MACHINERY_URI, 1001, "Machines")
LIFETIME_COUNTER_TYPE: Final = TypeRef(MACHINERY_URI, 1015, "MachineryLifetimeCounterType")
LIFETIME_VARIABLE_TYPE: Final = TypeRef(DI_URI, 468, "LifetimeVariableType")
MACHINE_IDENTIFICATION_TYPE: Final = TypeRef(MACHINERY_URI, 1012, "MachineIdentificationType")
ITEM_STATE_TYPE: Final = TypeRef(MACHINERY_URI, 1002, "MachineryItemState_StateMachineType")
OPERATION_MODE_TYPE: Final = TypeRef(MACHINERY_URI, 1008, "MachineryOperationModeStateMachineType")
NOT_AVAILABLE: Final = TypeRef(MACHINERY_URI, 5005, "NotAvailable")
OUT_OF_SERVICE: Final = TypeRef(MACHINERY_URI, 5004, "OutOfService")
NOT_EXECUTING: Final = TypeRef(MACHINERY_URI, 5007, "NotExecuting")
EXECUTING: Final = TypeRef(MACHINERY_URI, 5006, "Executing")
MODE_NONE: Final = TypeRef(MACHINERY_URI, 5024, "None")
MODE_MAINTENANCE: Final = TypeRef(MACHINERY_URI, 5025, "Maintenance")
MODE_SETUP: Final = TypeRef(MACHINERY_URI, 5027, "Setup")
MODE_PROCESSING: Final = TypeRef(MACHINERY_URI, 5026, "Processing")

ALL_REFS: Final = (
    DEVICE_SET,
    SOFTWARE_TYPE,
    MOTION_DEVICE_SYSTEM_TYPE,
    MOTION_DEVICE_TYPE,
    AXIS_TYPE,
    POWER_TRAIN_TYPE,
    MOTOR_TYPE,
    CONTROLLER_TYPE,
    SAFETY_STATE_TYPE,
    TASK_CONTROL_TYPE,
    CONTROLS,
    HAS_SAFETY_STATES,
    MOVES,
    REQUIRES,
    AXIS_MOTION_PROFILE,
    OPERATIONAL_MODE,
    MOTION_DEVICE_CATEGORY,
    MACHINES,
    MACHINE_IDENTIFICATION_TYPE,
    ITEM_STATE_TYPE,
    OPERATION_MODE_TYPE,
    NOT_AVAILABLE,
    OUT_OF_SERVICE,
    NOT_EXECUTING,
    EXECUTING,
    MODE_NONE,
    MODE_MAINTENANCE,
    MODE_SETUP,
    MODE_PROCESSING,
)

# Enumeration values (the specification's, as the NodeSet's EnumValues give them).
MOTION_PROFILE_ROTARY: Final = 1
CATEGORY_ARTICULATED_ROBOT: Final = 1
MODE_OTHER: Final = 0
MODE_MANUAL_REDUCED_SPEED: Final = 1
MODE_AUTOMATIC: Final = 3


class CompanionError(RuntimeError):
    """A NodeSet file that is missing, or a named node the imported models do not have."""


@dataclass(frozen=True, slots=True)
class Companion:
    """The imported models in one server: namespace indices, and how long the import took."""

    namespaces: dict[str, int]
    import_s: float

    def node_id(self, ref: TypeRef) -> ua.NodeId:
        return ua.NodeId(ref.identifier, self.namespaces[ref.uri])

    def name(self, ref: TypeRef) -> ua.QualifiedName:
        return ua.QualifiedName(ref.name, self.namespaces[ref.uri])

    @property
    def robotics(self) -> int:
        return self.namespaces[ROBOTICS_URI]

    @property
    def di(self) -> int:
        return self.namespaces[DI_URI]

    @property
    def machinery(self) -> int:
        return self.namespaces[MACHINERY_URI]


async def load(server: Server) -> Companion:
    """Import the NodeSet files into ``server`` (after ``init``) and check every ``TypeRef``."""
    started = time.perf_counter()
    # asyncua warns about every member the official files reference twice (HasComponent and
    # HasProperty): known, harmless, and dozens of lines at each start.
    importer_log = logging.getLogger("asyncua.common.xmlimporter")
    level = importer_log.level
    importer_log.setLevel(logging.ERROR)
    try:
        for file_name, uri in NODESETS:
            path = NODESET_DIR / file_name
            if not path.is_file():
                raise CompanionError(f"{path}: the {uri} model is missing from the installation")
            await server.import_xml(path)
    finally:
        importer_log.setLevel(level)
    array = await server.get_namespace_array()
    namespaces = {uri: array.index(uri) for _, uri in NODESETS if uri in array}
    missing = [uri for _, uri in NODESETS if uri not in namespaces]
    if missing:
        raise CompanionError(f"the NodeSet files did not declare {', '.join(missing)}")
    for file_name, _ in NODESETS:
        await _default_data_types(server, NODESET_DIR / file_name, array)
    companion = Companion(namespaces, time.perf_counter() - started)
    for ref in ALL_REFS:
        browse_name = server.get_node(companion.node_id(ref)).read_browse_name
        try:
            found = await browse_name()
        except ua.UaError:
            found = None
        if found != companion.name(ref):
            raise CompanionError(
                f"{ref.uri} i={ref.identifier}: expected {ref.name}, the model has {found}"
            )
    return companion


def declared_without_data_type(path: Path) -> list[tuple[str, str]]:
    """The variables and variable types of a NodeSet file that leave ``DataType`` to the
    schema's default: (their model's URI, their identifier as the file writes it: ``i=6017``)."""
    root = ET.parse(path).getroot()
    uris = ["http://opcfoundation.org/UA/"]
    uris += [uri.text or "" for uri in root.find(f"{_UA_NODESET}NamespaceUris") or []]
    found: list[tuple[str, str]] = []
    for element in root:
        if element.tag not in (f"{_UA_NODESET}UAVariable", f"{_UA_NODESET}UAVariableType"):
            continue
        if element.get("DataType") is not None:
            continue
        node_id = element.get("NodeId") or ""
        index, _, identifier = node_id.partition(";") if node_id.startswith("ns=") else ("", "", "")
        if index and identifier:
            found.append((uris[int(index[3:])], identifier))
    return found


async def _default_data_types(server: Server, path: Path, namespace_array: list[str]) -> None:
    """BaseDataType for each node ``declared_without_data_type`` that asyncua left Null."""
    for uri, identifier in declared_without_data_type(path):
        node_id = ua.NodeId.from_string(f"ns={namespace_array.index(uri)};{identifier}")
        node = server.get_node(node_id)
        current = await node.read_attribute(ua.AttributeIds.DataType)
        if current.Value is None or current.Value.Value is None or current.Value.Value.is_null():
            await node.write_attribute(
                ua.AttributeIds.DataType,
                ua.DataValue(ua.Variant(_BASE_DATA_TYPE, ua.VariantType.NodeId)),
            )
