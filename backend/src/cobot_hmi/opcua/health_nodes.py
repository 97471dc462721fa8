"""Layer: service (OPC UA). One robot's health (docs/health.md) in its vendor namespace.

Beside ``Status`` on the robot's object: ``Health`` with ``Verdict`` (the robot's: its worst
joint's, ok, watch or act) and per joint ``J<n>`` its ``Verdict`` and ``Reason``. Each joint's
reducer life used is a Machinery lifetime counter (OPC 40001-1, "MachineryLifetimeCounterType"):
``LifetimeCounters``, an add-in of the robot's machine (and a building block), holds
``J<n>ReducerLifeUsed`` of DI's ``LifetimeVariableType``, in % of the rated life, with its
``StartValue`` 0, ``LimitValue`` 100 and ``EngineeringUnits`` percent. Every value is Null
(``BadWaitingForInitialData``) until the service's first ``health`` event, then follows them,
written only when it changed (``values``).
"""

from __future__ import annotations

from typing import Final

from asyncua import ua

from cobot_hmi.opcua import companion as c
from cobot_hmi.opcua.bindings import HealthJoint, RobotNodes
from cobot_hmi.opcua.companion import Companion
from cobot_hmi.opcua.nodes import NodeBuilder, child_id
from cobot_hmi.opcua.units import unit_for

JOINTS: Final = 6
HAS_ADD_IN: Final = ua.NodeId(ua.ObjectIds.HasAddIn)
_STRING: Final = ua.NodeId(ua.ObjectIds.String)
_DOUBLE: Final = ua.NodeId(ua.ObjectIds.Double)


async def add_health(
    builder: NodeBuilder, companion: Companion, nodes: RobotNodes, system: ua.NodeId
) -> None:
    """``Health`` and ``LifetimeCounters`` under ``system`` (the robot's object)."""
    ns = nodes.namespace
    health = builder.add_object(
        system,
        child_id(system, "Health"),
        ua.QualifiedName("Health", ns),
        description="The robot's health: each joint's verdict and its reason (docs/health.md)",
    )
    nodes.health_verdict = _text(builder, health, "Verdict", ns, "ok, watch or act: the worst")
    counters = await builder.instantiate(
        system,
        companion.node_id(c.LIFETIME_COUNTER_TYPE),
        ua.QualifiedName("LifetimeCounters", companion.machinery),
        reference=HAS_ADD_IN,
    )
    builder.add_reference(child_id(system, "MachineryBuildingBlocks"), HAS_ADD_IN, counters)
    for joint in range(1, JOINTS + 1):
        folder = builder.add_object(
            health, child_id(health, f"J{joint}"), ua.QualifiedName(f"J{joint}", ns)
        )
        nodes.health_joints.append(
            HealthJoint(
                joint,
                _text(builder, folder, "Verdict", ns, "ok, watch or act"),
                _text(builder, folder, "Reason", ns, "the verdict in a sentence"),
                _life_used(builder, companion, nodes, counters, joint),
            )
        )


def _text(builder: NodeBuilder, parent: ua.NodeId, name: str, ns: int, words: str) -> ua.NodeId:
    return builder.add_variable(
        parent,
        child_id(parent, name),
        ua.QualifiedName(name, ns),
        ua.Variant("", ua.VariantType.String),
        _STRING,
        description=words,
    )


def _life_used(
    builder: NodeBuilder, companion: Companion, nodes: RobotNodes, counters: ua.NodeId, joint: int
) -> ua.NodeId:
    """A ``LifetimeVariableType`` variable: % of the reducer's rated life used."""
    name = f"J{joint}ReducerLifeUsed"
    node = builder.add_variable(
        counters,
        child_id(counters, name),
        ua.QualifiedName(name, nodes.namespace),
        ua.Variant(0.0, ua.VariantType.Double),
        _DOUBLE,
        type_definition=companion.node_id(c.LIFETIME_VARIABLE_TYPE),
        description=f"J{joint}'s reducer: its rated life used, % (docs/health.md)",
    )
    percent = ua.Variant(unit_for("%").information(), ua.VariantType.ExtensionObject)
    units = builder.add_property(
        node,
        ua.QualifiedName("EngineeringUnits", 0),
        ua.Variant(),
        ua.NodeId(ua.ObjectIds.EUInformation),
    )
    start = builder.add_property(
        node, ua.QualifiedName("StartValue", companion.di), ua.Variant(), _DOUBLE
    )
    limit = builder.add_property(
        node, ua.QualifiedName("LimitValue", companion.di), ua.Variant(), _DOUBLE
    )
    nodes.constants.extend(
        [
            (units, percent),
            (start, ua.Variant(0.0, ua.VariantType.Double)),
            (limit, ua.Variant(100.0, ua.VariantType.Double)),
        ]
    )
    return node
