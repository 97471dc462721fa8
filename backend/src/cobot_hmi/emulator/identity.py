"""Layer: emulator (no I/O here). Imports ``cobot_hmi.enip`` and the emulator's own modules.

The target's Identity object (class 0x01, instance 1; CIP Vol 1 Chapter 5, object library):
Get_Attributes_All (attributes 1–7), Get_Attribute_Single of attributes 1–8 and the class
attributes; every attribute is read-only. The values are ``enip.identity``'s
(``TargetSettings.identity``); attribute 8, State (USINT, 3 = operational), is the state the
ListIdentity reply carries, so both ways of asking agree.
"""

from __future__ import annotations

from cobot_hmi.emulator.replies import class_attribute, reply
from cobot_hmi.enip.cip import MessageRouterRequest, MessageRouterResponse, Service
from cobot_hmi.enip.epath import RequestPath
from cobot_hmi.enip.identity import IdentityInfo
from cobot_hmi.enip.status import GeneralStatus

CLASS_REVISION = 1
STATE_ATTRIBUTE = 8
"""Identity attribute 8, State (CIP Vol 1 §5-2.2): one USINT."""


def handle_identity_request(
    request: MessageRouterRequest, path: RequestPath, identity: IdentityInfo
) -> MessageRouterResponse:
    """An explicit request the Message Router found addressed to class 0x01."""
    if path.instance == 0:
        return class_attribute(request, path, CLASS_REVISION, 1, 1)
    if path.instance != 1:
        return reply(request, GeneralStatus.OBJECT_DOES_NOT_EXIST)
    if request.service == Service.GET_ATTRIBUTES_ALL:
        return reply(request, data=identity.encode_attributes_all())
    if request.service == Service.GET_ATTRIBUTE_SINGLE:
        if path.attribute is None:
            return reply(request, GeneralStatus.PATH_SEGMENT_ERROR)
        if path.attribute == STATE_ATTRIBUTE:
            return reply(request, data=bytes((identity.state,)))
        try:
            return reply(request, data=identity.encode_attribute(path.attribute))
        except KeyError:
            return reply(request, GeneralStatus.ATTRIBUTE_NOT_SUPPORTED)
    if request.service == Service.SET_ATTRIBUTE_SINGLE:
        return reply(request, GeneralStatus.ATTRIBUTE_NOT_SETTABLE)
    return reply(request, GeneralStatus.SERVICE_NOT_SUPPORTED)


__all__ = ["handle_identity_request"]
