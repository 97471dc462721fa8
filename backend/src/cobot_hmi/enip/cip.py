"""Layer: enip (pure). Imports only ``cobot_hmi.enip``.

Message Router requests and responses (the CIP body of an Unconnected Data item 0x00B2):
request = service, path size in words, padded path, data; response = service | 0x80,
reserved, general status, additional status size in words, additional status words, data.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum
from typing import Final

from cobot_hmi.enip.errors import EnipError, TruncatedError
from cobot_hmi.enip.status import describe

REPLY_FLAG: Final = 0x80


class Service(IntEnum):
    GET_ATTRIBUTES_ALL = 0x01
    SET_ATTRIBUTES_ALL = 0x02
    RESET = 0x05
    GET_ATTRIBUTE_SINGLE = 0x0E
    SET_ATTRIBUTE_SINGLE = 0x10
    FORWARD_CLOSE = 0x4E
    UNCONNECTED_SEND = 0x52
    FORWARD_OPEN = 0x54
    LARGE_FORWARD_OPEN = 0x5B


@dataclass(frozen=True, slots=True)
class MessageRouterRequest:
    service: int
    path: bytes
    data: bytes = b""

    def encode(self) -> bytes:
        if len(self.path) % 2:
            raise ValueError("a padded EPATH has an even number of bytes")
        return bytes((self.service, len(self.path) // 2)) + self.path + self.data


def decode_request(data: bytes | bytearray | memoryview) -> MessageRouterRequest:
    raw = bytes(data)
    if len(raw) < 2:
        raise TruncatedError("Message Router request", 2, len(raw))
    service, words = raw[0], raw[1]
    if service & REPLY_FLAG:
        raise EnipError(f"service 0x{service:02X} is a reply, not a request")
    end = 2 + words * 2
    if len(raw) < end:
        raise TruncatedError("Message Router request path", end, len(raw))
    return MessageRouterRequest(service, raw[2:end], raw[end:])


_RESPONSE_HEAD: Final = struct.Struct("<BBBB")


@dataclass(frozen=True, slots=True)
class MessageRouterResponse:
    service: int
    """The request's service code (without the reply flag)."""
    general_status: int = 0
    additional_status: tuple[int, ...] = ()
    data: bytes = b""

    @property
    def ok(self) -> bool:
        return self.general_status == 0

    def describe(self) -> str:
        return describe(self.general_status, self.additional_status)

    def encode(self) -> bytes:
        head = _RESPONSE_HEAD.pack(
            self.service | REPLY_FLAG, 0, self.general_status, len(self.additional_status)
        )
        words = struct.pack(f"<{len(self.additional_status)}H", *self.additional_status)
        return head + words + self.data


def decode_response(data: bytes | bytearray | memoryview) -> MessageRouterResponse:
    raw = bytes(data)
    if len(raw) < _RESPONSE_HEAD.size:
        raise TruncatedError("Message Router response", _RESPONSE_HEAD.size, len(raw))
    service, _reserved, general, words = _RESPONSE_HEAD.unpack_from(raw)
    if not service & REPLY_FLAG:
        raise EnipError(f"service 0x{service:02X} is not a reply (bit 7 clear)")
    end = _RESPONSE_HEAD.size + 2 * words
    if len(raw) < end:
        raise TruncatedError("Message Router additional status", end, len(raw))
    additional = struct.unpack_from(f"<{words}H", raw, _RESPONSE_HEAD.size)
    return MessageRouterResponse(service & ~REPLY_FLAG, general, additional, raw[end:])


def expect_service(response: MessageRouterResponse, service: int) -> None:
    """Check a response answers ``service``."""
    if response.service != service:
        raise EnipError(f"reply to service 0x{response.service:02X}, expected 0x{service:02X}")
