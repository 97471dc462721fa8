"""Layer: emulator (no I/O here). Imports ``cobot_hmi.enip``.

The explicit (unconnected) side of the target's object model: the Identity object and the
Assembly object. Each request gets a Message Router response with the proper CIP general
status; nothing here raises for a bad request (issue 3: "never a dropped socket").
"""

from __future__ import annotations

import struct
from typing import Protocol

from cobot_hmi.enip import epath
from cobot_hmi.enip.cip import MessageRouterRequest, MessageRouterResponse, Service
from cobot_hmi.enip.errors import PathError
from cobot_hmi.enip.identity import IdentityInfo
from cobot_hmi.enip.status import GeneralStatus

ASSEMBLY_DATA = 3
ASSEMBLY_SIZE = 4


class AssemblyAccess(Protocol):
    def assembly_instances(self) -> tuple[int, ...]:
        """Instances with data: configuration, O→T and T→O."""
        ...

    def assembly_data(self, instance: int) -> bytes:
        """An instance's data now (attribute 3)."""
        ...

    def set_assembly_data(self, instance: int, data: bytes) -> int:
        """Write attribute 3; returns the CIP general status."""
        ...


def _reply(
    request: MessageRouterRequest, status: int = 0, data: bytes = b""
) -> MessageRouterResponse:
    return MessageRouterResponse(request.service, status, (), data)


def handle_object_request(
    request: MessageRouterRequest, identity: IdentityInfo, assemblies: AssemblyAccess
) -> MessageRouterResponse:
    try:
        path = epath.decode_request_path(request.path)
    except PathError:
        return _reply(request, GeneralStatus.PATH_SEGMENT_ERROR)
    if path.class_id == epath.CLASS_IDENTITY:
        return _identity(request, path, identity)
    if path.class_id == epath.CLASS_ASSEMBLY:
        return _assembly(request, path, assemblies)
    return _reply(request, GeneralStatus.PATH_DESTINATION_UNKNOWN)


def _class_attribute(
    request: MessageRouterRequest,
    path: epath.RequestPath,
    revision: int,
    max_instance: int,
    instances: int,
) -> MessageRouterResponse:
    if request.service != Service.GET_ATTRIBUTE_SINGLE:
        return _reply(request, GeneralStatus.SERVICE_NOT_SUPPORTED)
    values = {1: revision, 2: max_instance, 3: instances}
    if path.attribute not in values:
        return _reply(request, GeneralStatus.ATTRIBUTE_NOT_SUPPORTED)
    return _reply(request, data=struct.pack("<H", values[path.attribute]))


def _identity(
    request: MessageRouterRequest, path: epath.RequestPath, identity: IdentityInfo
) -> MessageRouterResponse:
    if path.instance == 0:
        return _class_attribute(request, path, 1, 1, 1)
    if path.instance != 1:
        return _reply(request, GeneralStatus.OBJECT_DOES_NOT_EXIST)
    if request.service == Service.GET_ATTRIBUTES_ALL:
        return _reply(request, data=identity.encode_attributes_all())
    if request.service == Service.GET_ATTRIBUTE_SINGLE:
        if path.attribute is None:
            return _reply(request, GeneralStatus.PATH_SEGMENT_ERROR)
        try:
            return _reply(request, data=identity.encode_attribute(path.attribute))
        except KeyError:
            return _reply(request, GeneralStatus.ATTRIBUTE_NOT_SUPPORTED)
    if request.service == Service.SET_ATTRIBUTE_SINGLE:
        return _reply(request, GeneralStatus.ATTRIBUTE_NOT_SETTABLE)
    return _reply(request, GeneralStatus.SERVICE_NOT_SUPPORTED)


def _assembly(
    request: MessageRouterRequest, path: epath.RequestPath, assemblies: AssemblyAccess
) -> MessageRouterResponse:
    instances = assemblies.assembly_instances()
    if path.instance == 0:
        return _class_attribute(request, path, 2, max(instances), len(instances))
    if path.instance is None:
        return _reply(request, GeneralStatus.PATH_SEGMENT_ERROR)
    if path.instance not in instances:
        return _reply(request, GeneralStatus.OBJECT_DOES_NOT_EXIST)
    instance = path.instance
    if request.service == Service.GET_ATTRIBUTES_ALL:
        return _reply(request, data=assemblies.assembly_data(instance))
    if request.service == Service.GET_ATTRIBUTE_SINGLE:
        if path.attribute == ASSEMBLY_DATA:
            return _reply(request, data=assemblies.assembly_data(instance))
        if path.attribute == ASSEMBLY_SIZE:
            size = len(assemblies.assembly_data(instance))
            return _reply(request, data=struct.pack("<H", size))
        return _reply(request, GeneralStatus.ATTRIBUTE_NOT_SUPPORTED)
    if request.service == Service.SET_ATTRIBUTE_SINGLE:
        if path.attribute == ASSEMBLY_DATA:
            status = assemblies.set_assembly_data(instance, request.data)
            return _reply(request, status)
        if path.attribute == ASSEMBLY_SIZE:
            return _reply(request, GeneralStatus.ATTRIBUTE_NOT_SETTABLE)
        return _reply(request, GeneralStatus.ATTRIBUTE_NOT_SUPPORTED)
    return _reply(request, GeneralStatus.SERVICE_NOT_SUPPORTED)
