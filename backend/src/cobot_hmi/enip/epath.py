"""Layer: enip (pure). Imports only ``cobot_hmi.enip``.

Padded EPATHs (CIP Vol 1 Appendix C), once for every use on both sides: the request path of an
explicit request (Message Router, Vol 1 §2-4), and the connection path of a Forward Open,
Large Forward Open and Forward Close (Vol 1 §3-5.4). docs/protocol.md "Paths" says which
segments we send and accept.

Segments understood (Vol 1 C-1.4):

- **port** (C-1.4.1): ``000e pppp`` + link address; ``e`` = a link address size byte follows
  (then the address, padded to a whole word); port 15 = a 16-bit port number follows;
- **logical** (C-1.4.2): ``001 ttt ff`` with type ``ttt`` class (0), instance (1), member (2),
  connection point (3), attribute (4), and format ``ff`` 8-bit (0: ``<seg> <value>``), 16-bit
  (1: ``<seg> 00 <lo> <hi>``) or 32-bit (2: ``<seg> 00 <4 bytes>``, the pad byte keeping the
  value word-aligned in a padded path). Every width is accepted for every type, and they mean
  the same: ``20 06`` = ``21 00 06 00`` = ``22 00 06 00 00 00``;
- **electronic key** (C-1.4.2, logical special type, format 4): ``34 04`` + vendor (2), device
  type (2), product code (2), major revision (1, bit 7 = compatibility), minor revision (1);
- **simple data** (C-1.4.5): ``80 <words> <data>``, configuration data in a connection path.

Anything else (network, symbolic, the other special and service segments, reserved formats, a
segment cut short) raises :class:`PathError`: the target answers it with general status 0x04
in an explicit request and 0x01 / extended 0x0315 for a connection path, and the session goes
on. The encoders pick the shortest width unless told one (``width=8|16|32``).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Final, NamedTuple

from cobot_hmi.enip.errors import PathError
from cobot_hmi.enip.identity import IdentityInfo
from cobot_hmi.enip.status import ExtendedStatus


class LogicalType(IntEnum):
    """Bits 4–2 of a logical segment (CIP Vol 1 C-1.4.2)."""

    CLASS = 0
    INSTANCE = 1
    MEMBER = 2
    CONNECTION_POINT = 3
    ATTRIBUTE = 4
    SPECIAL = 5
    SERVICE_ID = 6


_LOGICAL: Final = 0x20
_FORMAT_8, _FORMAT_16, _FORMAT_32 = 0, 1, 2
_FORMAT_OF_WIDTH: Final = {8: _FORMAT_8, 16: _FORMAT_16, 32: _FORMAT_32}
_MAX_OF_WIDTH: Final = {8: 0xFF, 16: 0xFFFF, 32: 0xFFFF_FFFF}
_KEY_SEGMENT: Final = 0x34  # logical, special, electronic key
_KEY_FORMAT: Final = 0x04
_DATA_SEGMENT: Final = 0x80  # simple data segment
_KEY: Final = struct.Struct("<HHHBB")
_COMPATIBILITY_BIT: Final = 0x80
_PORT_EXTENDED_LINK: Final = 0x10
_PORT_EXTENDED_ID: Final = 0x0F

CLASS_IDENTITY: Final = 0x01
CLASS_MESSAGE_ROUTER: Final = 0x02
CLASS_ASSEMBLY: Final = 0x04
CLASS_CONNECTION_MANAGER: Final = 0x06


# --------------------------------------------------------------------------- encoding


def logical_segment(kind: LogicalType, value: int, *, width: int | None = None) -> bytes:
    """One logical segment; the shortest format that holds ``value`` unless ``width`` says."""
    if value < 0:
        raise ValueError(f"negative logical value {value}")
    if width is None:
        width = 8 if value <= 0xFF else 16 if value <= 0xFFFF else 32
    if width not in _FORMAT_OF_WIDTH:
        raise ValueError(f"logical segment width {width} (8, 16 or 32)")
    if value > _MAX_OF_WIDTH[width]:
        raise ValueError(f"logical value {value} does not fit {width} bits")
    head = _LOGICAL | kind << 2 | _FORMAT_OF_WIDTH[width]
    if width == 8:
        return bytes((head, value))
    return bytes((head, 0)) + value.to_bytes(width // 8, "little")


def class_segment(class_id: int, *, width: int | None = None) -> bytes:
    return logical_segment(LogicalType.CLASS, class_id, width=width)


def instance_segment(instance: int, *, width: int | None = None) -> bytes:
    return logical_segment(LogicalType.INSTANCE, instance, width=width)


def attribute_segment(attribute: int, *, width: int | None = None) -> bytes:
    return logical_segment(LogicalType.ATTRIBUTE, attribute, width=width)


def member_segment(member: int, *, width: int | None = None) -> bytes:
    return logical_segment(LogicalType.MEMBER, member, width=width)


def connection_point_segment(point: int, *, width: int | None = None) -> bytes:
    return logical_segment(LogicalType.CONNECTION_POINT, point, width=width)


def port_segment(port: int, link: bytes) -> bytes:
    """A port segment (CIP Vol 1 C-1.4.1): a one-byte link address fits the segment byte's
    neighbour; a longer one (an IP address as text) gets a size byte and a pad to a word."""
    if not 1 <= port <= 0xFFFF:
        raise ValueError(f"port {port} out of range")
    if not link or len(link) > 0xFF:
        raise ValueError("a port segment's link address has 1 to 255 bytes")
    extended = len(link) > 1
    head = (_PORT_EXTENDED_LINK if extended else 0) | min(port, _PORT_EXTENDED_ID)
    out = bytes((head,))
    if extended:
        out += bytes((len(link),))
    if port >= _PORT_EXTENDED_ID:
        out += port.to_bytes(2, "little")
    out += link
    return out + b"\x00" * (len(out) % 2)


class ElectronicKey(NamedTuple):
    """Electronic key format 4 (CIP Vol 1 C-1.4.2); a zero field matches anything.
    ``major_revision`` bit 7 is the compatibility flag."""

    vendor_id: int = 0
    device_type: int = 0
    product_code: int = 0
    major_revision: int = 0
    minor_revision: int = 0

    def encode(self) -> bytes:
        return bytes((_KEY_SEGMENT, _KEY_FORMAT)) + _KEY.pack(*self)

    @property
    def compatible(self) -> bool:
        """Compatibility set: a device that can emulate the revision is accepted (same major,
        a minor at least the key's); clear: the revision must be exactly the key's."""
        return bool(self.major_revision & _COMPATIBILITY_BIT)

    def mismatch(self, identity: IdentityInfo) -> int | None:
        """The extended status (0x0114 / 0x0115 / 0x0116) for a device this key does not
        admit, or ``None``. Zero fields are wildcards; an all-zero key admits any device."""
        if (self.vendor_id and self.vendor_id != identity.vendor_id) or (
            self.product_code and self.product_code != identity.product_code
        ):
            return ExtendedStatus.VENDOR_PRODUCT_MISMATCH
        if self.device_type and self.device_type != identity.device_type:
            return ExtendedStatus.DEVICE_TYPE_MISMATCH
        major = self.major_revision & ~_COMPATIBILITY_BIT
        minor = self.minor_revision
        if major and major != identity.revision_major:
            return ExtendedStatus.REVISION_MISMATCH
        if major and minor:
            if self.compatible and minor > identity.revision_minor:
                return ExtendedStatus.REVISION_MISMATCH
            if not self.compatible and minor != identity.revision_minor:
                return ExtendedStatus.REVISION_MISMATCH
        return None


def data_segment(data: bytes) -> bytes:
    if len(data) % 2:
        data += b"\x00"
    if len(data) // 2 > 0xFF:
        raise ValueError("simple data segment longer than 255 words")
    return bytes((_DATA_SEGMENT, len(data) // 2)) + data


def request_path(
    class_id: int, instance: int, attribute: int | None = None, *, width: int | None = None
) -> bytes:
    """``class / instance [/ attribute]`` as a padded EPATH."""
    path = class_segment(class_id, width=width) + instance_segment(instance, width=width)
    if attribute is not None:
        path += attribute_segment(attribute, width=width)
    return path


def connection_path(
    config_instance: int,
    o2t_point: int,
    t2o_point: int,
    *,
    key: ElectronicKey | None = None,
    config_data: bytes = b"",
    width: int | None = None,
) -> bytes:
    """``[key] 20 04 24 <cfg> 2C <O→T> 2C <T→O> [80 <words> <data>]``: consumed (O→T) then
    produced (T→O), the order CIP gives the application paths (Vol 1 C-1.5)."""
    path = key.encode() if key is not None else b""
    path += class_segment(CLASS_ASSEMBLY, width=width)
    path += instance_segment(config_instance, width=width)
    path += connection_point_segment(o2t_point, width=width)
    path += connection_point_segment(t2o_point, width=width)
    if config_data:
        path += data_segment(config_data)
    return path


# --------------------------------------------------------------------------- decoding


class Segment(NamedTuple):
    """One decoded segment: ``kind`` is ``class``, ``instance``, ``member``,
    ``connection_point``, ``attribute``, ``key``, ``data`` or ``port``; ``value`` the logical
    value, the port number, the key format or the data words; ``data`` the key's 8 bytes, the
    data segment's data or the port's link address."""

    kind: str
    value: int
    data: bytes = b""


_KIND_NAMES: Final[dict[int, str]] = {
    LogicalType.CLASS: "class",
    LogicalType.INSTANCE: "instance",
    LogicalType.MEMBER: "member",
    LogicalType.CONNECTION_POINT: "connection_point",
    LogicalType.ATTRIBUTE: "attribute",
}


def _need(path: bytes, offset: int, count: int, what: str) -> None:
    if offset + count > len(path):
        raise PathError(f"{what} at byte {offset}: needs {count} bytes, path has {len(path)}")


def _port(data: bytes, offset: int) -> tuple[Segment, int]:
    head = data[offset]
    port = head & 0x0F
    at = offset + 1
    size = 1
    if head & _PORT_EXTENDED_LINK:
        _need(data, at, 1, "port segment link size")
        size = data[at]
        at += 1
    if port == _PORT_EXTENDED_ID:
        _need(data, at, 2, "port segment port number")
        port = int.from_bytes(data[at : at + 2], "little")
        at += 2
    if port == 0 or size == 0:
        raise PathError(f"port segment at byte {offset}: port {port}, link size {size}")
    _need(data, at, size, "port segment link address")
    link = data[at : at + size]
    at += size
    at += (at - offset) % 2  # padded to a whole word
    _need(data, offset, at - offset, "port segment pad")
    return Segment("port", port, link), at


def decode_segments(path: bytes | bytearray | memoryview) -> list[Segment]:
    """Split a padded EPATH into segments; :class:`PathError` on anything not understood."""
    data = bytes(path)
    segments: list[Segment] = []
    offset = 0
    while offset < len(data):
        head = data[offset]
        kind = head >> 5
        if head == _KEY_SEGMENT:
            _need(data, offset, 2, "electronic key")
            if data[offset + 1] != _KEY_FORMAT:
                raise PathError(f"electronic key format {data[offset + 1]} (only 4 is known)")
            _need(data, offset, 2 + _KEY.size, "electronic key")
            raw = data[offset + 2 : offset + 2 + _KEY.size]
            segments.append(Segment("key", _KEY_FORMAT, raw))
            offset += 2 + _KEY.size
        elif kind == 1:  # logical
            name = _KIND_NAMES.get((head >> 2) & 0x07)
            if name is None:
                raise PathError(f"logical segment 0x{head:02X} at byte {offset} not supported")
            fmt = head & 0x03
            if fmt == _FORMAT_8:
                _need(data, offset, 2, name)
                value = data[offset + 1]
                offset += 2
            elif fmt == _FORMAT_16:
                _need(data, offset, 4, name)
                value = int.from_bytes(data[offset + 2 : offset + 4], "little")
                offset += 4
            elif fmt == _FORMAT_32:
                _need(data, offset, 6, name)
                value = int.from_bytes(data[offset + 2 : offset + 6], "little")
                offset += 6
            else:
                raise PathError(f"reserved logical format in segment 0x{head:02X}")
            segments.append(Segment(name, value))
        elif head == _DATA_SEGMENT:
            _need(data, offset, 2, "data segment")
            words = data[offset + 1]
            _need(data, offset + 2, words * 2, "data segment data")
            segments.append(Segment("data", words, data[offset + 2 : offset + 2 + words * 2]))
            offset += 2 + words * 2
        elif kind == 0:
            segment, offset = _port(data, offset)
            segments.append(segment)
        else:
            raise PathError(f"segment type 0x{head:02X} at byte {offset} not supported")
    return segments


@dataclass(frozen=True, slots=True)
class RequestPath:
    """A decoded request path: the object (class, instance) and its attribute or member."""

    class_id: int
    instance: int | None
    attribute: int | None
    member: int | None = None


def decode_request_path(path: bytes | bytearray | memoryview) -> RequestPath:
    """A Message Router request path: class, then optional instance, attribute, member
    (CIP Vol 1 C-1.5), each in any width."""
    class_id: int | None = None
    instance: int | None = None
    attribute: int | None = None
    member: int | None = None
    for seg in decode_segments(path):
        if seg.kind == "class" and class_id is None:
            class_id = seg.value
        elif seg.kind == "instance" and class_id is not None and instance is None:
            instance = seg.value
        elif seg.kind == "attribute" and instance is not None and attribute is None:
            attribute = seg.value
        elif seg.kind == "member" and instance is not None and member is None:
            member = seg.value
        else:
            raise PathError(f"unexpected {seg.kind} segment in a request path")
    if class_id is None:
        raise PathError("request path names no class")
    return RequestPath(class_id, instance, attribute, member)


@dataclass(frozen=True, slots=True)
class ConnectionPath:
    """A decoded Forward Open / Forward Close connection path.

    ``points`` are the connection points after the configuration instance, in path order
    (consumed O→T first, then produced T→O). An instance segment after the first one counts as
    a connection point too, as some originators write them that way.
    """

    class_id: int
    config_instance: int | None
    points: tuple[int, ...]
    key: ElectronicKey | None = None
    config_data: bytes = b""
    ports: tuple[int, ...] = field(default=())


def decode_connection_path(path: bytes | bytearray | memoryview) -> ConnectionPath:
    """Route (port segments) and electronic key first, then the application path: class,
    configuration instance, connection points, and configuration data (CIP Vol 1 C-1.5)."""
    key: ElectronicKey | None = None
    class_id: int | None = None
    config: int | None = None
    points: list[int] = []
    config_data = b""
    ports: list[int] = []
    for seg in decode_segments(path):
        if seg.kind == "key" and key is None and class_id is None:
            key = ElectronicKey._make(_KEY.unpack(seg.data))
        elif seg.kind == "port" and class_id is None and key is None:
            ports.append(seg.value)
        elif seg.kind == "class" and class_id is None:
            class_id = seg.value
        elif seg.kind == "instance" and class_id is not None and config is None and not points:
            config = seg.value
        elif (
            seg.kind in ("connection_point", "instance")
            and class_id is not None
            and not config_data
        ):
            points.append(seg.value)
        elif seg.kind == "data" and class_id is not None and not config_data:
            config_data = seg.data
        else:
            raise PathError(f"unexpected {seg.kind} segment in a connection path")
    if class_id is None:
        raise PathError("connection path names no class")
    return ConnectionPath(class_id, config, tuple(points), key, config_data, tuple(ports))


__all__ = [
    "CLASS_ASSEMBLY",
    "CLASS_CONNECTION_MANAGER",
    "CLASS_IDENTITY",
    "CLASS_MESSAGE_ROUTER",
    "ConnectionPath",
    "ElectronicKey",
    "LogicalType",
    "RequestPath",
    "Segment",
    "attribute_segment",
    "class_segment",
    "connection_path",
    "connection_point_segment",
    "data_segment",
    "decode_connection_path",
    "decode_request_path",
    "decode_segments",
    "instance_segment",
    "logical_segment",
    "member_segment",
    "port_segment",
]
