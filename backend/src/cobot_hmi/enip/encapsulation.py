"""Layer: enip (pure). Imports only ``cobot_hmi.enip``.

The encapsulation layer of EtherNet/IP on TCP 44818 (CIP Vol 2 §2-3, commands §2-4): a
24-byte little-endian header (command, length, session handle, status, sender context, options) and
the bodies of RegisterSession and SendRRData / SendUnitData.
"""

from __future__ import annotations

import struct
from enum import IntEnum
from typing import Final, NamedTuple

from cobot_hmi.enip.errors import LengthMismatchError, TruncatedError

HEADER: Final = struct.Struct("<HHII8sI")
HEADER_SIZE: Final = HEADER.size  # 24
MAX_DATA_SIZE: Final = 65511
"""The largest encapsulated data length (65535 minus the header)."""

ENIP_TCP_PORT: Final = 44818
ENIP_UDP_PORT: Final = 2222
"""The registered class 1 I/O port (docs/protocol.md "Cyclic packets, UDP 2222")."""

PROTOCOL_VERSION: Final = 1


class Command(IntEnum):
    """Encapsulation commands this project sends or answers."""

    NOP = 0x0000
    LIST_SERVICES = 0x0004
    LIST_IDENTITY = 0x0063
    LIST_INTERFACES = 0x0064
    REGISTER_SESSION = 0x0065
    UNREGISTER_SESSION = 0x0066
    SEND_RR_DATA = 0x006F
    SEND_UNIT_DATA = 0x0070


class EncapStatus(IntEnum):
    """Encapsulation status codes (the header's status field)."""

    SUCCESS = 0x0000
    INVALID_COMMAND = 0x0001
    INSUFFICIENT_MEMORY = 0x0002
    INCORRECT_DATA = 0x0003
    INVALID_SESSION = 0x0064
    INVALID_LENGTH = 0x0065
    UNSUPPORTED_PROTOCOL = 0x0069


ENCAP_STATUS_WORDS: Final = {
    EncapStatus.SUCCESS: "success",
    EncapStatus.INVALID_COMMAND: "invalid or unsupported encapsulation command",
    EncapStatus.INSUFFICIENT_MEMORY: "insufficient memory in the receiver",
    EncapStatus.INCORRECT_DATA: "poorly formed or incorrect data",
    EncapStatus.INVALID_SESSION: "invalid session handle",
    EncapStatus.INVALID_LENGTH: "invalid message length",
    EncapStatus.UNSUPPORTED_PROTOCOL: "unsupported encapsulation protocol revision",
}


def encap_status_words(status: int) -> str:
    """Words for an encapsulation status, ``0x....`` for an unknown one."""
    try:
        return ENCAP_STATUS_WORDS[EncapStatus(status)]
    except ValueError:
        return f"encapsulation status 0x{status:08X}"


class EncapHeader(NamedTuple):
    """The 24-byte header. ``length`` counts the bytes that follow it."""

    command: int
    length: int
    session: int
    status: int
    context: bytes
    options: int


def decode_header(data: bytes | bytearray | memoryview) -> EncapHeader:
    """Decode the first 24 bytes of ``data``."""
    if len(data) < HEADER_SIZE:
        raise TruncatedError("encapsulation header", HEADER_SIZE, len(data))
    return EncapHeader._make(HEADER.unpack_from(data))


def encode(
    command: int,
    data: bytes = b"",
    *,
    session: int = 0,
    status: int = 0,
    context: bytes = bytes(8),
    options: int = 0,
) -> bytes:
    """A whole encapsulation message: header then ``data``."""
    if len(data) > MAX_DATA_SIZE:
        raise ValueError(f"encapsulated data of {len(data)} bytes exceeds {MAX_DATA_SIZE}")
    return HEADER.pack(command, len(data), session, status, context, options) + data


class EncapMessage(NamedTuple):
    header: EncapHeader
    data: bytes


def decode(data: bytes | bytearray | memoryview) -> EncapMessage:
    """A whole message; its length field must match the bytes after the header exactly."""
    header = decode_header(data)
    actual = len(data) - HEADER_SIZE
    if header.length != actual:
        raise LengthMismatchError(
            f"encapsulation length field says {header.length} bytes, {actual} follow"
        )
    return EncapMessage(header, bytes(data[HEADER_SIZE:]))


# --------------------------------------------------------------------------- RegisterSession

_REGISTER: Final = struct.Struct("<HH")


class RegisterSessionData(NamedTuple):
    protocol_version: int
    options: int


def encode_register_session(protocol_version: int = PROTOCOL_VERSION, options: int = 0) -> bytes:
    return _REGISTER.pack(protocol_version, options)


def decode_register_session(data: bytes | bytearray | memoryview) -> RegisterSessionData:
    if len(data) != _REGISTER.size:
        raise LengthMismatchError(f"RegisterSession data must be 4 bytes, got {len(data)}")
    return RegisterSessionData._make(_REGISTER.unpack(data))


# ------------------------------------------------------------ SendRRData / SendUnitData

_RR_PREFIX: Final = struct.Struct("<IH")


class RRDataPrefix(NamedTuple):
    """Interface handle (0 for CIP) and timeout (s) in front of the CPF item list."""

    interface_handle: int
    timeout_s: int


def encode_rr_prefix(timeout_s: int = 0, interface_handle: int = 0) -> bytes:
    return _RR_PREFIX.pack(interface_handle, timeout_s)


def decode_rr_prefix(data: bytes | bytearray | memoryview) -> tuple[RRDataPrefix, memoryview]:
    """The prefix and a view of the CPF bytes after it."""
    if len(data) < _RR_PREFIX.size:
        raise TruncatedError("SendRRData/SendUnitData prefix", _RR_PREFIX.size, len(data))
    prefix = RRDataPrefix._make(_RR_PREFIX.unpack_from(data))
    return prefix, memoryview(data)[_RR_PREFIX.size :]
