"""Layer: enip (pure). Imports only ``cobot_hmi.enip``.

The Connection Manager's services (CIP Vol 1 §3-5.4): Forward Open (0x54) and Large Forward
Open (0x5B) with their network connection parameters, their success and failure replies,
Forward Close (0x4E), and the Unconnected Send (0x52) wrapper some originators put around them.
Only the service data is here; the Message Router header is ``cip``'s. The connection paths
are ``epath``'s, in every width it knows (``connection_path()`` decodes one).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum
from typing import Final

from cobot_hmi.enip import epath
from cobot_hmi.enip.cip import MessageRouterRequest, Service
from cobot_hmi.enip.errors import EnipError, LengthMismatchError, TruncatedError

CONNECTION_MANAGER_INSTANCE: Final = 1
CONNECTION_MANAGER_PATH: Final = epath.request_path(
    epath.CLASS_CONNECTION_MANAGER, CONNECTION_MANAGER_INSTANCE
)
"""What we send: ``20 06 24 01``; a target accepts any width that decodes to the same object
(``21 00 06 00 25 00 01 00`` alike: ``epath.decode_request_path``)."""

TRANSPORT_CLASS1_CYCLIC: Final = 0x01
"""Transport type/trigger: class 1, cyclic trigger, client direction."""


class ConnectionType(IntEnum):
    NULL = 0
    MULTICAST = 1
    POINT_TO_POINT = 2
    RESERVED = 3


class Priority(IntEnum):
    LOW = 0
    HIGH = 1
    SCHEDULED = 2
    URGENT = 3


@dataclass(frozen=True, slots=True)
class NetworkParams:
    """Network connection parameters. ``size_bytes`` is the connection size: data + 2 for the
    CIP sequence count + 4 when a 32-bit run/idle header is present (docs/protocol.md)."""

    size_bytes: int
    connection_type: ConnectionType = ConnectionType.POINT_TO_POINT
    priority: Priority = Priority.SCHEDULED
    variable: bool = False
    redundant_owner: bool = False

    def encode16(self) -> int:
        if not 0 <= self.size_bytes <= 0x1FF:
            raise ValueError(f"connection size {self.size_bytes} needs a Large Forward Open")
        return (
            self.redundant_owner << 15
            | self.connection_type << 13
            | self.priority << 10
            | self.variable << 9
            | self.size_bytes
        )

    def encode32(self) -> int:
        if not 0 <= self.size_bytes <= 0xFFFF:
            raise ValueError(f"connection size {self.size_bytes} out of range")
        return (
            self.redundant_owner << 31
            | self.connection_type << 29
            | self.priority << 26
            | self.variable << 25
            | self.size_bytes
        )

    @classmethod
    def decode16(cls, word: int) -> NetworkParams:
        return cls(
            word & 0x1FF,
            ConnectionType(word >> 13 & 3),
            Priority(word >> 10 & 3),
            bool(word >> 9 & 1),
            bool(word >> 15 & 1),
        )

    @classmethod
    def decode32(cls, dword: int) -> NetworkParams:
        return cls(
            dword & 0xFFFF,
            ConnectionType(dword >> 29 & 3),
            Priority(dword >> 26 & 3),
            bool(dword >> 25 & 1),
            bool(dword >> 31 & 1),
        )


def connection_timeout_us(rpi_us: int, multiplier: int) -> int:
    """Connection timeout = RPI × (4 << multiplier) (CIP Vol 1 §3-5.4.1; docs/protocol.md)."""
    return rpi_us * (4 << multiplier)


# --------------------------------------------------------------------------- Forward Open

_FO_HEAD: Final = struct.Struct("<BBIIHHIB3x")
_FO_NORMAL: Final = struct.Struct("<IHIHBB")
_FO_LARGE: Final = struct.Struct("<IIIIBB")


@dataclass(frozen=True, slots=True)
class ForwardOpenRequest:
    o2t_connection_id: int
    t2o_connection_id: int
    connection_serial: int
    vendor_id: int
    originator_serial: int
    timeout_multiplier: int
    o2t_rpi_us: int
    o2t_params: NetworkParams
    t2o_rpi_us: int
    t2o_params: NetworkParams
    path: bytes
    transport: int = TRANSPORT_CLASS1_CYCLIC
    large: bool = False
    priority_tick: int = 0x0A
    timeout_ticks: int = 0x0E

    @property
    def service(self) -> int:
        return Service.LARGE_FORWARD_OPEN if self.large else Service.FORWARD_OPEN

    @property
    def triplet(self) -> tuple[int, int, int]:
        """The connection's identity: (connection serial, vendor, originator serial)."""
        return (self.connection_serial, self.vendor_id, self.originator_serial)

    def encode(self) -> bytes:
        if len(self.path) % 2:
            raise ValueError("connection path must be whole 16-bit words")
        head = _FO_HEAD.pack(
            self.priority_tick,
            self.timeout_ticks,
            self.o2t_connection_id,
            self.t2o_connection_id,
            self.connection_serial,
            self.vendor_id,
            self.originator_serial,
            self.timeout_multiplier,
        )
        if self.large:
            body = _FO_LARGE.pack(
                self.o2t_rpi_us,
                self.o2t_params.encode32(),
                self.t2o_rpi_us,
                self.t2o_params.encode32(),
                self.transport,
                len(self.path) // 2,
            )
        else:
            body = _FO_NORMAL.pack(
                self.o2t_rpi_us,
                self.o2t_params.encode16(),
                self.t2o_rpi_us,
                self.t2o_params.encode16(),
                self.transport,
                len(self.path) // 2,
            )
        return head + body + self.path

    def request(self) -> MessageRouterRequest:
        return MessageRouterRequest(self.service, CONNECTION_MANAGER_PATH, self.encode())

    def connection_path(self) -> epath.ConnectionPath:
        """The decoded connection path; :class:`PathError` when it does not decode."""
        return epath.decode_connection_path(self.path)


def decode_forward_open(data: bytes | bytearray | memoryview, *, large: bool) -> ForwardOpenRequest:
    raw = bytes(data)
    tail = _FO_LARGE if large else _FO_NORMAL
    fixed = _FO_HEAD.size + tail.size
    what = "Large Forward Open" if large else "Forward Open"
    if len(raw) < fixed:
        raise TruncatedError(what, fixed, len(raw))
    tick, ticks, o2t_id, t2o_id, serial, vendor, orig_serial, mult = _FO_HEAD.unpack_from(raw)
    o2t_rpi, o2t_p, t2o_rpi, t2o_p, transport, words = tail.unpack_from(raw, _FO_HEAD.size)
    if len(raw) != fixed + 2 * words:
        raise LengthMismatchError(
            f"{what}: path size says {2 * words} bytes, {len(raw) - fixed} follow"
        )
    decode_params = NetworkParams.decode32 if large else NetworkParams.decode16
    return ForwardOpenRequest(
        o2t_id,
        t2o_id,
        serial,
        vendor,
        orig_serial,
        mult,
        o2t_rpi,
        decode_params(o2t_p),
        t2o_rpi,
        decode_params(t2o_p),
        raw[fixed:],
        transport,
        large,
        tick,
        ticks,
    )


_FO_REPLY: Final = struct.Struct("<IIHHIIIBx")


@dataclass(frozen=True, slots=True)
class ForwardOpenReply:
    """A successful reply; the APIs are the actual packet intervals the target will use."""

    o2t_connection_id: int
    t2o_connection_id: int
    connection_serial: int
    vendor_id: int
    originator_serial: int
    o2t_api_us: int
    t2o_api_us: int
    application_reply: bytes = b""

    def encode(self) -> bytes:
        reply = self.application_reply + b"\x00" * (len(self.application_reply) % 2)
        return (
            _FO_REPLY.pack(
                self.o2t_connection_id,
                self.t2o_connection_id,
                self.connection_serial,
                self.vendor_id,
                self.originator_serial,
                self.o2t_api_us,
                self.t2o_api_us,
                len(reply) // 2,
            )
            + reply
        )


def decode_forward_open_reply(data: bytes | bytearray | memoryview) -> ForwardOpenReply:
    raw = bytes(data)
    if len(raw) < _FO_REPLY.size:
        raise TruncatedError("Forward Open reply", _FO_REPLY.size, len(raw))
    o2t_id, t2o_id, serial, vendor, orig_serial, o2t_api, t2o_api, words = _FO_REPLY.unpack_from(
        raw
    )
    end = _FO_REPLY.size + 2 * words
    if len(raw) < end:
        raise TruncatedError("Forward Open application reply", end, len(raw))
    return ForwardOpenReply(
        o2t_id, t2o_id, serial, vendor, orig_serial, o2t_api, t2o_api, raw[_FO_REPLY.size : end]
    )


_FAILURE: Final = struct.Struct("<HHIBx")


@dataclass(frozen=True, slots=True)
class ConnectionFailureReply:
    """The data of an unsuccessful Forward Open or Forward Close reply (the statuses are in
    the Message Router response)."""

    connection_serial: int
    vendor_id: int
    originator_serial: int
    remaining_path_size: int = 0

    def encode(self) -> bytes:
        return _FAILURE.pack(
            self.connection_serial,
            self.vendor_id,
            self.originator_serial,
            self.remaining_path_size,
        )


def decode_failure_reply(data: bytes | bytearray | memoryview) -> ConnectionFailureReply:
    raw = bytes(data)
    if len(raw) < _FAILURE.size:
        raise TruncatedError("connection failure reply", _FAILURE.size, len(raw))
    return ConnectionFailureReply(*_FAILURE.unpack_from(raw))


# --------------------------------------------------------------------------- Forward Close

_FC_HEAD: Final = struct.Struct("<BBHHIBx")


@dataclass(frozen=True, slots=True)
class ForwardCloseRequest:
    connection_serial: int
    vendor_id: int
    originator_serial: int
    path: bytes
    priority_tick: int = 0x0A
    timeout_ticks: int = 0x0E

    @property
    def triplet(self) -> tuple[int, int, int]:
        return (self.connection_serial, self.vendor_id, self.originator_serial)

    def encode(self) -> bytes:
        if len(self.path) % 2:
            raise ValueError("connection path must be whole 16-bit words")
        return (
            _FC_HEAD.pack(
                self.priority_tick,
                self.timeout_ticks,
                self.connection_serial,
                self.vendor_id,
                self.originator_serial,
                len(self.path) // 2,
            )
            + self.path
        )

    def request(self) -> MessageRouterRequest:
        return MessageRouterRequest(Service.FORWARD_CLOSE, CONNECTION_MANAGER_PATH, self.encode())

    def connection_path(self) -> epath.ConnectionPath:
        """The decoded connection path; :class:`PathError` when it does not decode."""
        return epath.decode_connection_path(self.path)


def decode_forward_close(data: bytes | bytearray | memoryview) -> ForwardCloseRequest:
    raw = bytes(data)
    if len(raw) < _FC_HEAD.size:
        raise TruncatedError("Forward Close", _FC_HEAD.size, len(raw))
    tick, ticks, serial, vendor, orig_serial, words = _FC_HEAD.unpack_from(raw)
    if len(raw) != _FC_HEAD.size + 2 * words:
        raise LengthMismatchError(
            f"Forward Close: path size says {2 * words} bytes, {len(raw) - _FC_HEAD.size} follow"
        )
    return ForwardCloseRequest(serial, vendor, orig_serial, raw[_FC_HEAD.size :], tick, ticks)


_FC_REPLY: Final = struct.Struct("<HHIBx")


@dataclass(frozen=True, slots=True)
class ForwardCloseReply:
    connection_serial: int
    vendor_id: int
    originator_serial: int
    application_reply: bytes = b""

    def encode(self) -> bytes:
        reply = self.application_reply + b"\x00" * (len(self.application_reply) % 2)
        return (
            _FC_REPLY.pack(
                self.connection_serial, self.vendor_id, self.originator_serial, len(reply) // 2
            )
            + reply
        )


def decode_forward_close_reply(data: bytes | bytearray | memoryview) -> ForwardCloseReply:
    raw = bytes(data)
    if len(raw) < _FC_REPLY.size:
        raise TruncatedError("Forward Close reply", _FC_REPLY.size, len(raw))
    serial, vendor, orig_serial, words = _FC_REPLY.unpack_from(raw)
    end = _FC_REPLY.size + 2 * words
    if len(raw) < end:
        raise TruncatedError("Forward Close application reply", end, len(raw))
    return ForwardCloseReply(serial, vendor, orig_serial, raw[_FC_REPLY.size : end])


# --------------------------------------------------------------------------- Unconnected Send

_US_HEAD: Final = struct.Struct("<BBH")


@dataclass(frozen=True, slots=True)
class UnconnectedSend:
    """An Unconnected Send (0x52): an embedded request and the route path to its target."""

    message: bytes
    route_path: bytes
    priority_tick: int = 0x0A
    timeout_ticks: int = 0x0E

    def encode(self) -> bytes:
        pad = b"\x00" if len(self.message) % 2 else b""
        return (
            _US_HEAD.pack(self.priority_tick, self.timeout_ticks, len(self.message))
            + self.message
            + pad
            + bytes((len(self.route_path) // 2, 0))
            + self.route_path
        )


def decode_unconnected_send(data: bytes | bytearray | memoryview) -> UnconnectedSend:
    raw = bytes(data)
    if len(raw) < _US_HEAD.size:
        raise TruncatedError("Unconnected Send", _US_HEAD.size, len(raw))
    tick, ticks, size = _US_HEAD.unpack_from(raw)
    start = _US_HEAD.size
    end = start + size
    if len(raw) < end:
        raise TruncatedError("Unconnected Send embedded message", end, len(raw))
    message = raw[start:end]
    end += size % 2
    if len(raw) < end + 2:
        raise TruncatedError("Unconnected Send route path size", end + 2, len(raw))
    words = raw[end]
    route = raw[end + 2 :]
    if len(route) != 2 * words:
        raise EnipError(f"Unconnected Send route path: size says {2 * words}, {len(route)} follow")
    return UnconnectedSend(message, route, tick, ticks)
