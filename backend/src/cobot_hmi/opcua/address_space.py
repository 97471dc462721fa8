"""Layer: service (OPC UA). The address space: the companion models, then every robot.

Each robot gets a namespace of its own (``urn:cobot-hmi:robot:<name>``: its NodeIds stay the
same whatever other robots the cell has) holding its Robotics instances (``robotics``), its
whole I/O layout (``layout_nodes``), its Machinery building blocks (``machinery``: found from
``Objects/Machines``), and beside them on the robot's object: ``Status`` (``ConnectionState``,
``ControlHolder``), ``Health`` and its lifetime counters (``health_nodes``) and, with writes on
only, the methods ``TakeControl`` and ``ReleaseControl`` (linked by ``writes``).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Final

from asyncua import Server, ua

from cobot_hmi.opcua.bindings import RobotNodes
from cobot_hmi.opcua.companion import Companion
from cobot_hmi.opcua.health_nodes import add_health
from cobot_hmi.opcua.layout_nodes import LayoutBuilder
from cobot_hmi.opcua.machinery import MachineryBuilder
from cobot_hmi.opcua.nodes import NodeBuilder, child_id
from cobot_hmi.opcua.robotics import RoboticsBuilder

NAMESPACE_PREFIX: Final = "urn:cobot-hmi:robot:"


def robot_namespace(robot: str) -> str:
    return NAMESPACE_PREFIX + robot


async def build(
    server: Server, companion: Companion, robots: Sequence[str], *, writable: bool
) -> tuple[dict[str, RobotNodes], float]:
    """Every robot's nodes (committed), and how long building them took, s."""
    started = time.perf_counter()
    builder = NodeBuilder(server)
    built: dict[str, RobotNodes] = {}
    for robot in robots:
        namespace = await server.register_namespace(robot_namespace(robot))
        nodes = RobotNodes(robot, namespace)
        system = await RoboticsBuilder(builder, companion, nodes).add()
        LayoutBuilder(builder, nodes, writable=writable).add(system)
        await MachineryBuilder(builder, companion, nodes).add(system)
        _status_and_control(builder, nodes, system, writable=writable)
        await add_health(builder, companion, nodes, system)
        await builder.commit()
        built[robot] = nodes
    return built, time.perf_counter() - started


def _status_and_control(
    builder: NodeBuilder, nodes: RobotNodes, system: ua.NodeId, *, writable: bool
) -> None:
    ns = nodes.namespace
    status = builder.add_object(
        system,
        child_id(system, "Status"),
        ua.QualifiedName("Status", ns),
        description="The service's link to the robot and who holds control of its outputs",
    )
    string = ua.NodeId(ua.ObjectIds.String)
    nodes.connection_state = builder.add_variable(
        status,
        child_id(status, "ConnectionState"),
        ua.QualifiedName("ConnectionState", ns),
        ua.Variant("", ua.VariantType.String),
        string,
        description="The class 1 connection: connecting, connected, lost, refused or closed",
    )
    nodes.control_holder = builder.add_variable(
        status,
        child_id(status, "ControlHolder"),
        ua.QualifiedName("ControlHolder", ns),
        ua.Variant("", ua.VariantType.String),
        string,
        description="The user holding control of the robot's outputs (empty: nobody)",
    )
    if not writable:  # a session that cannot write must not hold control (writes.py)
        return
    result = ua.Argument(
        Name="Holder",
        DataType=string,
        ValueRank=ua.ValueRank.Scalar,
        Description=ua.LocalizedText("the user holding control afterwards (empty: nobody)"),
    )
    nodes.take_control = builder.add_method(
        system,
        ua.QualifiedName("TakeControl", ns),
        "Take control of the robot's outputs for this session (the operator role)",
        outputs=[result],
    )
    nodes.release_control = builder.add_method(
        system,
        ua.QualifiedName("ReleaseControl", ns),
        "Release this session's control of the robot's outputs",
        outputs=[result],
    )
