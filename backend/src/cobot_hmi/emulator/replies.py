"""Layer: emulator (no I/O here). Imports ``cobot_hmi.enip``.

What every object of the target answers alike: a Message Router response with a general status,
and the class attributes (instance 0) that every CIP object has (CIP Vol 1 Chapter 4, common
class attributes: revision, max instance, number of instances).
"""

from __future__ import annotations

import struct

from cobot_hmi.enip.cip import MessageRouterRequest, MessageRouterResponse, Service
from cobot_hmi.enip.epath import RequestPath
from cobot_hmi.enip.status import GeneralStatus


def reply(
    request: MessageRouterRequest, status: int = GeneralStatus.SUCCESS, data: bytes = b""
) -> MessageRouterResponse:
    return MessageRouterResponse(request.service, status, (), data)


def class_attribute(
    request: MessageRouterRequest,
    path: RequestPath,
    revision: int,
    max_instance: int,
    instances: int,
) -> MessageRouterResponse:
    """A Get_Attribute_Single of class attribute 1, 2 or 3 (instance 0)."""
    if request.service != Service.GET_ATTRIBUTE_SINGLE:
        return reply(request, GeneralStatus.SERVICE_NOT_SUPPORTED)
    values = {1: revision, 2: max_instance, 3: instances}
    if path.attribute not in values:
        return reply(request, GeneralStatus.ATTRIBUTE_NOT_SUPPORTED)
    return reply(request, data=struct.pack("<H", values[path.attribute]))


__all__ = ["class_attribute", "reply"]
