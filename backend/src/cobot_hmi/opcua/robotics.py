"""Layer: service (OPC UA). One robot in the Robotics companion specification's shape.

Under ``Objects/DeviceSet`` (DI) each robot is a ``MotionDeviceSystemType`` named after it,
with (OPC 40010-1; the types' mandatory members made by ``NodeBuilder.instantiate``):

- ``MotionDevices/<robot>`` (``MotionDeviceType``, ``ARTICULATED_ROBOT``): Manufacturer
  "Doosan Robotics", Model, SerialNumber and ProductCode from the robot's CIP identity;
  ``Axes/Axis1…6`` (``AxisType``, MotionProfile ``ROTARY``; ``ParameterSet/ActualPosition`` [°]
  and ``ActualSpeed`` [°/s] with their ``EURange``: the arm's joint limits, ``cobot_hmi.arms``);
  ``PowerTrains/PowerTrain1…6`` each with ``Motor1`` (``MotorType``:
  ``ParameterSet/MotorTemperature`` [°C], and the vendor's ``MotorCurrent`` [A],
  ``JointTorque`` and ``ExternalTorque`` [N·m] beside it); a powertrain ``Moves`` its axis,
  the axis ``Requires`` it.
- ``Controllers/<robot>`` (``ControllerType``): the identity's nameplate, ``SoftwareRevision``
  the frame's controller version (also ``Software/Controller``, a DI ``SoftwareType``); it
  ``Controls`` the motion device and ``HasSafetyStates`` the safety state.
- ``SafetyStates/<robot>`` (``SafetyStateType``): ``ParameterSet/EmergencyStop`` and
  ``ProtectiveStop`` from the frame's flags and state, ``OperationalMode`` read from the state.

Mandatory members the implicit I/O does not carry (the speed override, the task program, the
controller's user level) are Null with ``BadNotSupported``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Final

from asyncua import ua

from cobot_hmi.arms import ARMS
from cobot_hmi.codec import Frame
from cobot_hmi.generated.frames import RobotState
from cobot_hmi.opcua import companion as c
from cobot_hmi.opcua.bindings import Binding, JointRange, RobotNodes
from cobot_hmi.opcua.companion import Companion
from cobot_hmi.opcua.nodes import NodeBuilder, child_id
from cobot_hmi.opcua.units import unit_for

MANUFACTURER: Final = "Doosan Robotics"
JOINTS: Final = 6
_DOUBLE: Final = ua.NodeId(ua.ObjectIds.Double)
_ANALOG_UNIT_TYPE: Final = ua.NodeId(ua.ObjectIds.AnalogUnitType)
_MANUAL_STATES: Final = frozenset(
    {RobotState.MANUAL_STANDBY, RobotState.MANUAL_JOGGING, RobotState.MANUAL_HANDGUIDING}
)
_AUTOMATIC_STATES: Final = frozenset(
    {
        RobotState.STANDALONE_STANDBY,
        RobotState.STANDALONE_RUNNING,
        RobotState.COLLABORATIVE_STANDBY,
        RobotState.COLLABORATIVE_RUNNING,
        RobotState.HIGH_PRIORITY_RUNNING,
    }
)


def emergency_stop(frame: Frame) -> bool:
    return frame.emergency_stopped or frame.robot_state == RobotState.EMERGENCY_STOP


def protective_stop(frame: Frame) -> bool:
    return frame.safety_stopped or frame.robot_state == RobotState.INTERRUPTED


def operational_mode(frame: Frame) -> int:
    """The project's reading of the state (docs/operations.md, "OPC UA"): teaching is manual at
    reduced speed, the task program's states automatic, everything else other."""
    if frame.robot_state in _MANUAL_STATES:
        return c.MODE_MANUAL_REDUCED_SPEED
    if frame.robot_state in _AUTOMATIC_STATES:
        return c.MODE_AUTOMATIC
    return c.MODE_OTHER


def _joint(field: str, joint: int) -> Callable[[Frame], object]:
    position = Frame._fields.index(field)

    def read(frame: Frame) -> object:
        values = frame[position]
        assert isinstance(values, tuple)
        return values[joint]

    return read


class RoboticsBuilder:
    """Adds one robot's Robotics instances (module docstring) and records their bindings."""

    def __init__(self, builder: NodeBuilder, companion: Companion, nodes: RobotNodes) -> None:
        self._b = builder
        self._c = companion
        self._nodes = nodes
        self._ns = nodes.namespace

    def _name(self, text: str) -> ua.QualifiedName:
        return ua.QualifiedName(text, self._ns)

    def _rob(self, text: str) -> ua.QualifiedName:
        return ua.QualifiedName(text, self._c.robotics)

    def _di(self, text: str) -> ua.QualifiedName:
        return ua.QualifiedName(text, self._c.di)

    async def add(self) -> ua.NodeId:
        """The robot's ``MotionDeviceSystemType`` object in ``DeviceSet``; its NodeId."""
        robot = self._nodes.robot
        system = await self._b.instantiate(
            self._c.node_id(c.DEVICE_SET),
            self._c.node_id(c.MOTION_DEVICE_SYSTEM_TYPE),
            self._name(robot),
            nodeid=ua.NodeId(robot, self._ns),
        )
        device = await self._motion_device(child_id(system, "MotionDevices"))
        controller = await self._controller(child_id(system, "Controllers"))
        safety = await self._safety_state(child_id(system, "SafetyStates"))
        self._b.add_reference(controller, self._c.node_id(c.CONTROLS), device)
        self._b.add_reference(controller, self._c.node_id(c.HAS_SAFETY_STATES), safety)
        return system

    def _nameplate(self, node: ua.NodeId, *, identity: bool) -> None:
        manufacturer = child_id(node, "Manufacturer")
        self._constant(manufacturer, ua.LocalizedText(MANUFACTURER))
        if identity:
            self._nodes.models.append(child_id(node, "Model"))
            self._nodes.serial_numbers.append(child_id(node, "SerialNumber"))
            self._nodes.product_codes.append(child_id(node, "ProductCode"))

    def _constant(
        self, node: ua.NodeId, value: object, variant: ua.VariantType | None = None
    ) -> None:
        self._nodes.constants.append((node, ua.Variant(value, variant)))

    async def _motion_device(self, folder: ua.NodeId) -> ua.NodeId:
        robot = self._nodes.robot
        device = await self._b.instantiate(
            folder, self._c.node_id(c.MOTION_DEVICE_TYPE), self._name(robot)
        )
        self._nameplate(device, identity=True)
        self._constant(
            child_id(device, "MotionDeviceCategory"),
            c.CATEGORY_ARTICULATED_ROBOT,
            ua.VariantType.Int32,
        )
        self._nodes.unsupported.append(child_id(child_id(device, "ParameterSet"), "SpeedOverride"))
        axes, trains = child_id(device, "Axes"), child_id(device, "PowerTrains")
        for joint in range(JOINTS):
            axis = await self._axis(axes, joint)
            train = await self._power_train(trains, joint)
            self._b.add_reference(train, self._c.node_id(c.MOVES), axis)
            self._b.add_reference(axis, self._c.node_id(c.REQUIRES), train)
        return device

    async def _axis(self, folder: ua.NodeId, joint: int) -> ua.NodeId:
        axis = await self._b.instantiate(
            folder, self._c.node_id(c.AXIS_TYPE), self._name(f"Axis{joint + 1}")
        )
        self._constant(
            child_id(axis, "MotionProfile"), c.MOTION_PROFILE_ROTARY, ua.VariantType.Int32
        )
        parameters = child_id(axis, "ParameterSet")
        position = child_id(parameters, "ActualPosition")
        self._analog(position, "joint_position", joint, "degree", declared=True)
        self._range(position, joint, speed=False)
        speed = child_id(parameters, "ActualSpeed")
        self._b.add_variable(
            parameters,
            speed,
            self._rob("ActualSpeed"),
            ua.Variant(),
            _DOUBLE,
            type_definition=_ANALOG_UNIT_TYPE,
        )
        self._analog(speed, "joint_velocity", joint, "degree/s", declared=False)
        self._range(speed, joint, speed=True)
        return axis

    def _range(self, node: ua.NodeId, joint: int, *, speed: bool) -> None:
        arm_joint = ARMS[0].joints[joint]
        limit = arm_joint.max_speed_deg_s if speed else arm_joint.limit_deg
        range_node = self._b.add_property(
            node,
            ua.QualifiedName("EURange", 0),
            ua.Variant(ua.Range(Low=-limit, High=limit), ua.VariantType.ExtensionObject),
            ua.NodeId(ua.ObjectIds.Range),
        )
        self._nodes.joint_ranges.append(JointRange(range_node, joint, speed))

    def _analog(
        self, node: ua.NodeId, field: str, joint: int, unit: str, *, declared: bool
    ) -> None:
        """Bind ``node`` (a Double) to joint ``joint`` of ``field``; its EngineeringUnits."""
        information = ua.Variant(unit_for(unit).information(), ua.VariantType.ExtensionObject)
        units = child_id(node, "EngineeringUnits")
        if declared:  # the member's own EngineeringUnits, made by instantiate: its value
            self._nodes.constants.append((units, information))
        else:
            self._b.add_property(
                node,
                ua.QualifiedName("EngineeringUnits", 0),
                information,
                ua.NodeId(ua.ObjectIds.EUInformation),
            )
        self._nodes.frame.append(
            Binding(node, _joint(field, joint), ua.VariantType.Double, Frame._fields.index(field))
        )

    async def _power_train(self, folder: ua.NodeId, joint: int) -> ua.NodeId:
        train = await self._b.instantiate(
            folder, self._c.node_id(c.POWER_TRAIN_TYPE), self._name(f"PowerTrain{joint + 1}")
        )
        motor = await self._b.instantiate(
            train, self._c.node_id(c.MOTOR_TYPE), self._name("Motor1")
        )
        self._nameplate(motor, identity=False)
        for member in ("Model", "ProductCode", "SerialNumber"):
            text = ua.LocalizedText("") if member == "Model" else ""
            self._constant(child_id(motor, member), text)
        parameters = child_id(motor, "ParameterSet")
        self._analog(
            child_id(parameters, "MotorTemperature"),
            "joint_motor_temperature",
            joint,
            "°C",
            declared=True,
        )
        for name, field, unit, what in (
            ("MotorCurrent", "joint_motor_current", "A", "motor current"),
            ("JointTorque", "joint_torque", "N·m", "joint torque"),
            ("ExternalTorque", "joint_external_torque", "N·m", "external torque"),
        ):
            node = child_id(parameters, name)
            self._b.add_variable(
                parameters,
                node,
                self._name(name),
                ua.Variant(),
                _DOUBLE,
                type_definition=_ANALOG_UNIT_TYPE,
                description=f"J{joint + 1} {what} (the robot's T→O frame, {field})",
            )
            self._analog(node, field, joint, unit, declared=False)
        return train

    async def _controller(self, folder: ua.NodeId) -> ua.NodeId:
        robot = self._nodes.robot
        controller = await self._b.instantiate(
            folder, self._c.node_id(c.CONTROLLER_TYPE), self._name(robot)
        )
        self._nameplate(controller, identity=True)
        revision = self._b.add_property(
            controller,
            self._di("SoftwareRevision"),
            ua.Variant(),
            ua.NodeId(ua.ObjectIds.String),
        )
        self._nodes.software_revisions.append(revision)
        software = await self._b.instantiate(
            child_id(controller, "Software"),
            self._c.node_id(c.SOFTWARE_TYPE),
            self._name("Controller"),
        )
        self._constant(child_id(software, "Manufacturer"), ua.LocalizedText(MANUFACTURER))
        self._constant(child_id(software, "Model"), ua.LocalizedText("Robot controller software"))
        self._nodes.software_revisions.append(child_id(software, "SoftwareRevision"))
        self._nodes.unsupported.append(child_id(child_id(controller, "CurrentUser"), "Level"))
        task = await self._b.instantiate(
            child_id(controller, "TaskControls"),
            self._c.node_id(c.TASK_CONTROL_TYPE),
            self._name("TaskControl1"),
        )
        self._constant(child_id(task, "ComponentName"), ua.LocalizedText(f"{robot} task program"))
        task_parameters = child_id(task, "ParameterSet")
        self._nodes.unsupported.append(child_id(task_parameters, "TaskProgramLoaded"))
        self._nodes.unsupported.append(child_id(task_parameters, "TaskProgramName"))
        return controller

    async def _safety_state(self, folder: ua.NodeId) -> ua.NodeId:
        safety = await self._b.instantiate(
            folder, self._c.node_id(c.SAFETY_STATE_TYPE), self._name(self._nodes.robot)
        )
        parameters = child_id(safety, "ParameterSet")
        for name, read, variant in (
            ("EmergencyStop", emergency_stop, ua.VariantType.Boolean),
            ("ProtectiveStop", protective_stop, ua.VariantType.Boolean),
            ("OperationalMode", operational_mode, ua.VariantType.Int32),
        ):
            self._nodes.frame.append(Binding(child_id(parameters, name), read, variant))
        return safety
