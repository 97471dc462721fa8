"""Layer: service (OPC UA). Every robot as a machine of OPC 40001-1 (Machinery Basic Building
Blocks), as OPC 40010-1's annex on Machinery shows a robot: what dashboards that know
Machinery (umati) look for.

``Objects/Machines`` (Machinery's entry point) ``Organizes`` each robot's
``MotionDeviceSystemType`` object (the one in ``DeviceSet``), which gets:

- ``Identification`` (``MachineIdentificationType``, ``HasAddIn``): Manufacturer, SerialNumber
  and ProductInstanceUri (mandatory), Model, ProductCode, SoftwareRevision and ManufacturerUri,
  from the robot's CIP identity and the frame's controller version, as the Robotics nameplates.
- ``MachineryBuildingBlocks`` (a folder) with ``HasAddIn`` to that ``Identification``, to
  ``MachineryItemState`` (``MachineryItemState_StateMachineType``) and to
  ``MachineryOperationMode`` (``MachineryOperationModeStateMachineType``), whose
  ``CurrentState`` and ``CurrentState/Id`` follow the robot's state (``item_state``,
  ``operation_mode``; the mapping is in docs/api.md, "OPC UA: the Machinery building blocks").
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Final

from asyncua import ua

from cobot_hmi.codec import Frame
from cobot_hmi.generated.frames import RobotState
from cobot_hmi.opcua import companion as c
from cobot_hmi.opcua.bindings import MachineState, RobotNodes, StateMachineBinding
from cobot_hmi.opcua.companion import Companion, TypeRef
from cobot_hmi.opcua.nodes import ORGANIZES, NodeBuilder, child_id
from cobot_hmi.opcua.robotics import MANUFACTURER, emergency_stop, protective_stop

MANUFACTURER_URI: Final = "https://www.doosanrobotics.com"
HAS_ADD_IN: Final = ua.NodeId(ua.ObjectIds.HasAddIn)
_FOLDER_TYPE: Final = ua.NodeId(ua.ObjectIds.FolderType)
_STRING: Final = ua.NodeId(ua.ObjectIds.String)

_S = RobotState
_EXECUTING: Final = frozenset(
    {
        _S.MANUAL_JOGGING,
        _S.MANUAL_HANDGUIDING,
        _S.STANDALONE_RUNNING,
        _S.COLLABORATIVE_RUNNING,
        _S.HIGH_PRIORITY_RUNNING,
        _S.AUTO_MEASURE,
        _S.HANDGUIDING_CONTROL_RUNNING,
    }
)
_NOT_EXECUTING: Final = frozenset(
    {
        _S.MANUAL_STANDBY,
        _S.STANDALONE_STANDBY,
        _S.COLLABORATIVE_STANDBY,
        _S.HANDGUIDING_CONTROL_STANDBY,
    }
)
_OUT_OF_SERVICE: Final = frozenset(
    {
        _S.EMERGENCY_STOP,
        _S.SAFE_OFF,
        _S.INTERRUPTED,
        _S.RECOVERY_STANDBY,
        _S.RECOVERY_JOGGING,
        _S.RECOVERY_HANDGUIDING,
        _S.BACKDRIVE_HOLD,
        _S.BACKDRIVE_RELEASE,
        _S.BACKDRIVE_RELEASE_BY_COCKPIT,
    }
)
_SETUP: Final = frozenset(
    {_S.MANUAL_STANDBY, _S.MANUAL_JOGGING, _S.MANUAL_HANDGUIDING, _S.AUTO_MEASURE}
)
_MAINTENANCE: Final = frozenset(
    {
        _S.RECOVERY_STANDBY,
        _S.RECOVERY_JOGGING,
        _S.RECOVERY_HANDGUIDING,
        _S.BACKDRIVE_HOLD,
        _S.BACKDRIVE_RELEASE,
        _S.BACKDRIVE_RELEASE_BY_COCKPIT,
    }
)
_PROCESSING: Final = frozenset(
    {
        _S.STANDALONE_STANDBY,
        _S.STANDALONE_RUNNING,
        _S.COLLABORATIVE_STANDBY,
        _S.COLLABORATIVE_RUNNING,
        _S.HIGH_PRIORITY_RUNNING,
        _S.HANDGUIDING_CONTROL_STANDBY,
        _S.HANDGUIDING_CONTROL_RUNNING,
    }
)


ITEM_STATES: Final = (c.NOT_AVAILABLE, c.OUT_OF_SERVICE, c.NOT_EXECUTING, c.EXECUTING)
MODES: Final = (c.MODE_NONE, c.MODE_MAINTENANCE, c.MODE_SETUP, c.MODE_PROCESSING)


def item_state(frame: Frame | None) -> TypeRef:
    """OPC 40001-1 §12's MachineryItemState of the robot: no frame (the link down, none yet),
    initializing or a state outside the table: NotAvailable; stopped by the emergency stop, a
    protective stop or a fault, or in recovery or backdrive: OutOfService; a standby state:
    NotExecuting; moving (a task program, jogging, hand-guiding, measuring): Executing."""
    if frame is None:
        return c.NOT_AVAILABLE
    if emergency_stop(frame) or protective_stop(frame) or frame.robot_state in _OUT_OF_SERVICE:
        return c.OUT_OF_SERVICE
    if frame.robot_state in _EXECUTING:
        return c.EXECUTING
    if frame.robot_state in _NOT_EXECUTING:
        return c.NOT_EXECUTING
    return c.NOT_AVAILABLE


def operation_mode(frame: Frame | None) -> TypeRef:
    """OPC 40001-1 §13's MachineryOperationMode: teaching and measuring the tool: Setup;
    recovery and backdrive: Maintenance; the task program's states: Processing; anything else
    (no frame, a stop, initializing) says no mode: None."""
    if frame is None:
        return c.MODE_NONE
    if frame.robot_state in _SETUP:
        return c.MODE_SETUP
    if frame.robot_state in _MAINTENANCE:
        return c.MODE_MAINTENANCE
    if frame.robot_state in _PROCESSING:
        return c.MODE_PROCESSING
    return c.MODE_NONE


class MachineryBuilder:
    """Adds one robot's Machinery building blocks (module docstring), records their bindings."""

    def __init__(self, builder: NodeBuilder, companion: Companion, nodes: RobotNodes) -> None:
        self._b = builder
        self._c = companion
        self._nodes = nodes

    async def add(self, system: ua.NodeId) -> None:
        """Under ``system`` (the robot's MotionDeviceSystem), found from ``Machines``."""
        self._b.add_reference(self._c.node_id(c.MACHINES), ORGANIZES, system)
        identification = await self._identification(system)
        blocks = self._b.add_object(
            system,
            child_id(system, "MachineryBuildingBlocks"),
            ua.QualifiedName("MachineryBuildingBlocks", self._c.machinery),
            type_definition=_FOLDER_TYPE,
        )
        self._b.add_reference(blocks, HAS_ADD_IN, identification)
        await self._state_machine(
            blocks, c.ITEM_STATE_TYPE, "MachineryItemState", item_state, ITEM_STATES
        )
        await self._state_machine(
            blocks, c.OPERATION_MODE_TYPE, "MachineryOperationMode", operation_mode, MODES
        )

    def _di(self, text: str) -> ua.QualifiedName:
        return ua.QualifiedName(text, self._c.di)

    async def _identification(self, system: ua.NodeId) -> ua.NodeId:
        node = await self._b.instantiate(
            system,
            self._c.node_id(c.MACHINE_IDENTIFICATION_TYPE),
            self._di("Identification"),
            reference=HAS_ADD_IN,
        )
        nodes = self._nodes
        nodes.constants.append(
            (child_id(node, "Manufacturer"), ua.Variant(ua.LocalizedText(MANUFACTURER)))
        )
        nodes.serial_numbers.append(child_id(node, "SerialNumber"))
        nodes.product_instance_uris.append(child_id(node, "ProductInstanceUri"))
        model = self._b.add_property(
            node, self._di("Model"), ua.Variant(), ua.NodeId(ua.ObjectIds.LocalizedText)
        )
        nodes.models.append(model)
        nodes.product_codes.append(
            self._b.add_property(node, self._di("ProductCode"), ua.Variant(), _STRING)
        )
        nodes.software_revisions.append(
            self._b.add_property(node, self._di("SoftwareRevision"), ua.Variant(), _STRING)
        )
        uri = self._b.add_property(node, self._di("ManufacturerUri"), ua.Variant(), _STRING)
        nodes.constants.append((uri, ua.Variant(MANUFACTURER_URI, ua.VariantType.String)))
        return node

    async def _state_machine(
        self,
        blocks: ua.NodeId,
        type_ref: TypeRef,
        name: str,
        state_of: Callable[[Frame | None], TypeRef],
        states: tuple[TypeRef, ...],
    ) -> None:
        machine = await self._b.instantiate(
            blocks,
            self._c.node_id(type_ref),
            ua.QualifiedName(name, self._c.machinery),
            reference=HAS_ADD_IN,
        )
        current = child_id(machine, "CurrentState")
        by_ref = {ref: MachineState(ref.name, self._c.node_id(ref)) for ref in states}

        def read(frame: Frame | None) -> MachineState:
            return by_ref[state_of(frame)]

        self._nodes.state_machines.append(
            StateMachineBinding(current, child_id(current, "Id"), read)
        )
