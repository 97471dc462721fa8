"""Layer: service (OPC UA). Adding nodes to the server's address space, in batches.

``NodeBuilder`` collects objects, variables, properties, methods and references and adds them
in one AddNodes/AddReferences call each (``commit``), on the server's own session. Its
``instantiate`` makes an instance of an object type as OPC UA Part 3 §6.4 says: the type's
mandatory members (its own and its supertypes', the nearest declaration winning, recursively
through each member's own instance declarations), never its optional members or placeholders
(``<AxisIdentifier>``: the builder's caller adds those, with their real names). Every NodeId is
a string: the instance's path of browse names joined by dots (``m1013.Axes.Axis1``), so a
client's configuration by NodeId survives a restart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Final

from asyncua import Server, ua

HAS_COMPONENT: Final = ua.NodeId(ua.ObjectIds.HasComponent)
HAS_PROPERTY: Final = ua.NodeId(ua.ObjectIds.HasProperty)
ORGANIZES: Final = ua.NodeId(ua.ObjectIds.Organizes)
_MANDATORY: Final = ua.NodeId(ua.ObjectIds.ModellingRule_Mandatory)
_BASE_OBJECT_TYPE: Final = ua.NodeId(ua.ObjectIds.BaseObjectType)
_BASE_VARIABLE_TYPE: Final = ua.NodeId(ua.ObjectIds.BaseVariableType)
_BASE_DATA_VARIABLE_TYPE: Final = ua.NodeId(ua.ObjectIds.BaseDataVariableType)
_PROPERTY_TYPE: Final = ua.NodeId(ua.ObjectIds.PropertyType)
READ: Final = ua.AccessLevel.CurrentRead.mask
READ_WRITE: Final = ua.AccessLevel.CurrentRead.mask | ua.AccessLevel.CurrentWrite.mask


class BuildError(RuntimeError):
    """The server refused a node or a reference (a bug in the model built here)."""


@dataclass(frozen=True, slots=True)
class _Member:
    """A mandatory instance declaration of a type: what an instance gets a copy of."""

    declaration: ua.NodeId
    name: ua.QualifiedName
    node_class: ua.NodeClass
    reference: ua.NodeId
    type_definition: ua.NodeId


def child_id(parent: ua.NodeId, name: str) -> ua.NodeId:
    """The string NodeId of ``parent``'s member called ``name``."""
    return ua.NodeId(f"{parent.Identifier}.{name}", parent.NamespaceIndex)


@dataclass
class NodeBuilder:
    """Collects nodes and references for one ``commit`` (see the module docstring)."""

    server: Server
    _nodes: list[ua.AddNodesItem] = field(default_factory=list)
    _references: list[ua.AddReferencesItem] = field(default_factory=list)
    _members: dict[ua.NodeId, list[_Member]] = field(default_factory=dict)
    """Per type or declaration: its mandatory members (read once per server)."""

    # ------------------------------------------------------------ plain nodes

    def add_object(
        self,
        parent: ua.NodeId,
        nodeid: ua.NodeId,
        name: ua.QualifiedName,
        *,
        type_definition: ua.NodeId = _BASE_OBJECT_TYPE,
        reference: ua.NodeId = HAS_COMPONENT,
        description: str = "",
    ) -> ua.NodeId:
        attributes = ua.ObjectAttributes()
        attributes.DisplayName = ua.LocalizedText(name.Name)
        if description:
            attributes.Description = ua.LocalizedText(description)
        attributes.EventNotifier = 0
        self._add(
            parent,
            nodeid,
            name,
            node_class=ua.NodeClass.Object,
            reference=reference,
            type_definition=type_definition,
            attributes=attributes,
        )
        return nodeid

    def add_variable(
        self,
        parent: ua.NodeId,
        nodeid: ua.NodeId,
        name: ua.QualifiedName,
        value: ua.Variant,
        data_type: ua.NodeId,
        *,
        type_definition: ua.NodeId = _BASE_DATA_VARIABLE_TYPE,
        reference: ua.NodeId = HAS_COMPONENT,
        access: int = READ,
        description: str = "",
        value_rank: int = ua.ValueRank.Scalar,
    ) -> ua.NodeId:
        attributes = ua.VariableAttributes()
        attributes.DisplayName = ua.LocalizedText(name.Name)
        if description:
            attributes.Description = ua.LocalizedText(description)
        attributes.Value = value
        attributes.DataType = data_type
        attributes.ValueRank = value_rank
        attributes.AccessLevel = access
        attributes.UserAccessLevel = access
        attributes.Historizing = False
        self._add(
            parent,
            nodeid,
            name,
            node_class=ua.NodeClass.Variable,
            reference=reference,
            type_definition=type_definition,
            attributes=attributes,
        )
        return nodeid

    def add_property(
        self,
        parent: ua.NodeId,
        name: ua.QualifiedName,
        value: ua.Variant,
        data_type: ua.NodeId,
        *,
        value_rank: int = ua.ValueRank.Scalar,
    ) -> ua.NodeId:
        return self.add_variable(
            parent,
            child_id(parent, name.Name),
            name,
            value,
            data_type,
            type_definition=_PROPERTY_TYPE,
            reference=HAS_PROPERTY,
            value_rank=value_rank,
        )

    def add_method(
        self,
        parent: ua.NodeId,
        name: ua.QualifiedName,
        description: str,
        *,
        outputs: Sequence[ua.Argument] = (),
    ) -> ua.NodeId:
        """A method without input arguments (its callback is linked by the caller)."""
        nodeid = child_id(parent, name.Name)
        attributes = ua.MethodAttributes()
        attributes.DisplayName = ua.LocalizedText(name.Name)
        attributes.Description = ua.LocalizedText(description)
        attributes.Executable = True
        attributes.UserExecutable = True
        item = ua.AddNodesItem()
        item.RequestedNewNodeId = nodeid
        item.BrowseName = name
        item.NodeClass = ua.NodeClass.Method
        item.ParentNodeId = parent
        item.ReferenceTypeId = HAS_COMPONENT
        item.NodeAttributes = attributes
        self._nodes.append(item)
        if outputs:
            self.add_property(
                nodeid,
                ua.QualifiedName("OutputArguments", 0),
                ua.Variant(list(outputs), ua.VariantType.ExtensionObject),
                ua.NodeId(ua.ObjectIds.Argument),
                value_rank=ua.ValueRank.OneDimension,
            )
        return nodeid

    def add_reference(self, source: ua.NodeId, reference: ua.NodeId, target: ua.NodeId) -> None:
        item = ua.AddReferencesItem()
        item.SourceNodeId = source
        item.ReferenceTypeId = reference
        item.IsForward = True
        item.TargetNodeId = target
        item.TargetNodeClass = ua.NodeClass.Object
        self._references.append(item)

    def _add(
        self,
        parent: ua.NodeId,
        nodeid: ua.NodeId,
        name: ua.QualifiedName,
        *,
        node_class: ua.NodeClass,
        reference: ua.NodeId,
        type_definition: ua.NodeId,
        attributes: Any,
    ) -> None:
        item = ua.AddNodesItem()
        item.RequestedNewNodeId = nodeid
        item.BrowseName = name
        item.NodeClass = node_class
        item.ParentNodeId = parent
        item.ReferenceTypeId = reference
        item.TypeDefinition = type_definition
        item.NodeAttributes = attributes
        self._nodes.append(item)

    async def commit(self) -> None:
        """Add everything collected, in order (parents first), then the references."""
        nodes, self._nodes = self._nodes, []
        references, self._references = self._references, []
        session = self.server.iserver.isession
        results = await session.add_nodes(nodes)
        for item, result in zip(nodes, results, strict=True):
            if not result.StatusCode.is_good():
                raise BuildError(f"adding {item.RequestedNewNodeId}: {result.StatusCode}")
        if references:
            statuses = await session.add_references(references)
            for reference, status in zip(references, statuses, strict=True):
                if not status.is_good():
                    raise BuildError(
                        f"reference {reference.SourceNodeId} → {reference.TargetNodeId}: {status}"
                    )

    # ------------------------------------------------------------ instances of types

    async def instantiate(
        self,
        parent: ua.NodeId,
        type_definition: ua.NodeId,
        name: ua.QualifiedName,
        *,
        nodeid: ua.NodeId | None = None,
        reference: ua.NodeId = HAS_COMPONENT,
    ) -> ua.NodeId:
        """An object of ``type_definition`` with its mandatory members (module docstring);
        its NodeId is ``nodeid`` or ``parent``'s member path."""
        nodeid = nodeid if nodeid is not None else child_id(parent, name.Name)
        self.add_object(parent, nodeid, name, type_definition=type_definition, reference=reference)
        await self._add_members(nodeid, await self._mandatory_of_type(type_definition))
        return nodeid

    async def _add_members(self, instance: ua.NodeId, members: list[_Member]) -> None:
        for member in members:
            nodeid = child_id(instance, member.name.Name)
            own = await self._mandatory_members(member.declaration)
            if member.node_class == ua.NodeClass.Object:
                self.add_object(
                    instance,
                    nodeid,
                    member.name,
                    type_definition=member.type_definition,
                    reference=member.reference,
                )
            elif member.node_class == ua.NodeClass.Variable:
                await self._copy_variable(instance, nodeid, member)
            else:  # a mandatory method: none in the types this server instantiates
                raise BuildError(f"{member.name}: mandatory {member.node_class.name} not supported")
            inherited = await self._mandatory_of_type(member.type_definition)
            names = {(m.name.NamespaceIndex, m.name.Name) for m in own}
            extra = [m for m in inherited if (m.name.NamespaceIndex, m.name.Name) not in names]
            await self._add_members(nodeid, own + extra)

    async def _copy_variable(self, parent: ua.NodeId, nodeid: ua.NodeId, member: _Member) -> None:
        node = self.server.get_node(member.declaration)
        data_type, value_rank, value = await node.read_attributes(
            [ua.AttributeIds.DataType, ua.AttributeIds.ValueRank, ua.AttributeIds.Value]
        )
        assert data_type.Value is not None and value_rank.Value is not None
        initial = value.Value if value.Value is not None else ua.Variant()
        self.add_variable(
            parent,
            nodeid,
            member.name,
            initial,
            data_type.Value.Value,
            type_definition=member.type_definition,
            reference=member.reference,
            value_rank=value_rank.Value.Value,
        )

    async def _mandatory_of_type(self, type_definition: ua.NodeId) -> list[_Member]:
        """The mandatory members of a type and of its supertypes (the nearest declaration of a
        browse name wins), stopping at the base object and variable types."""
        members: list[_Member] = []
        names: set[tuple[int, str]] = set()
        current: ua.NodeId | None = type_definition
        while current is not None and current not in (_BASE_OBJECT_TYPE, _BASE_VARIABLE_TYPE):
            for member in await self._mandatory_members(current):
                key = (member.name.NamespaceIndex, member.name.Name)
                if key not in names:
                    names.add(key)
                    members.append(member)
            supertypes = await self.server.get_node(current).get_references(
                ua.ObjectIds.HasSubtype, ua.BrowseDirection.Inverse
            )
            current = supertypes[0].NodeId if supertypes else None
        return members

    async def _mandatory_members(self, node_id: ua.NodeId) -> list[_Member]:
        cached = self._members.get(node_id)
        if cached is not None:
            return cached
        members: dict[tuple[int, str], _Member] = {}
        node = self.server.get_node(node_id)
        for description in await node.get_children_descriptions():
            child = self.server.get_node(description.NodeId)
            rules = await child.get_referenced_nodes(ua.ObjectIds.HasModellingRule)
            if not rules or rules[0].nodeid != _MANDATORY:
                continue
            member = _Member(
                description.NodeId,
                description.BrowseName,
                description.NodeClass,
                description.ReferenceTypeId,
                description.TypeDefinition,
            )
            key = (member.name.NamespaceIndex, member.name.Name)
            # Some NodeSets reference a property twice (HasComponent and HasProperty): one
            # member, through the reference its type calls for.
            if key not in members or (
                member.type_definition == _PROPERTY_TYPE and member.reference == HAS_PROPERTY
            ):
                members[key] = member
        found = list(members.values())
        self._members[node_id] = found
        return found
