"""Layer: enip (pure). Imports only ``cobot_hmi.enip``.

Padded EPATH segments (ethernetip.md "Forward Open"): logical segments for class, instance,
attribute and connection point in their 8-, 16- and 32-bit forms, the electronic key
(``34 04`` + 8 bytes), simple data segments (``80 <words> <data>``) and port segments.
A request path names one attribute of one object; a connection path names the configuration
instance and the connection points of a Forward Open.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Final, NamedTuple

from cobot_hmi.enip.errors import PathError

# Logical segment: 001 <type:3> <format:2> (CIP Vol 1, C-1.4.2)
_LOGICAL: Final = 0x20
_CLASS, _INSTANCE, _MEMBER, _CONNECTION_POINT, _ATTRIBUTE, _SPECIAL = 0, 1, 2, 3, 4, 5
_FORMAT_8, _FORMAT_16, _FORMAT_32 = 0, 1, 2
_KEY_SEGMENT: Final = 0x34  # logical, special, electronic key
_KEY_FORMAT: Final = 0x04
_DATA_SEGMENT: Final = 0x80  # simple data segment
_KEY: Final = struct.Struct("<HHHBB")

CLASS_IDENTITY: Final = 0x01
CLASS_MESSAGE_ROUTER: Final = 0x02
CLASS_ASSEMBLY: Final = 0x04
CLASS_CONNECTION_MANAGER: Final = 0x06


def _logical(kind: int, value: int) -> bytes:
    if value < 0:
        raise ValueError(f"negative logical value {value}")
    if value <= 0xFF:
        return bytes((_LOGICAL | kind << 2 | _FORMAT_8, value))
    if value <= 0xFFFF:
        return bytes((_LOGICAL | kind << 2 | _FORMAT_16, 0)) + value.to_bytes(2, "little")
    if value <= 0xFFFFFFFF:
        return bytes((_LOGICAL | kind << 2 | _FORMAT_32, 0)) + value.to_bytes(4, "little")
    raise ValueError(f"logical value {value} too large")


def class_segment(class_id: int) -> bytes:
    return _logical(_CLASS, class_id)


def instance_segment(instance: int) -> bytes:
    return _logical(_INSTANCE, instance)


def attribute_segment(attribute: int) -> bytes:
    return _logical(_ATTRIBUTE, attribute)


def connection_point_segment(point: int) -> bytes:
    return _logical(_CONNECTION_POINT, point)


class ElectronicKey(NamedTuple):
    """Electronic key format 4; zero fields match anything. ``major_revision`` bit 7 is the
    compatibility flag."""

    vendor_id: int = 0
    device_type: int = 0
    product_code: int = 0
    major_revision: int = 0
    minor_revision: int = 0

    def encode(self) -> bytes:
        return bytes((_KEY_SEGMENT, _KEY_FORMAT)) + _KEY.pack(*self)


def data_segment(data: bytes) -> bytes:
    if len(data) % 2:
        data += b"\x00"
    if len(data) // 2 > 0xFF:
        raise ValueError("simple data segment longer than 255 words")
    return bytes((_DATA_SEGMENT, len(data) // 2)) + data


def request_path(class_id: int, instance: int, attribute: int | None = None) -> bytes:
    """``class / instance [/ attribute]`` as a padded EPATH."""
    path = class_segment(class_id) + instance_segment(instance)
    if attribute is not None:
        path += attribute_segment(attribute)
    return path


def connection_path(
    config_instance: int,
    o2t_point: int,
    t2o_point: int,
    *,
    key: ElectronicKey | None = None,
    config_data: bytes = b"",
) -> bytes:
    """``[key] 20 04 24 <cfg> 2C <O→T> 2C <T→O> [80 <words> <data>]``: consumed (O→T) then
    produced (T→O), the order CIP gives the application paths."""
    path = key.encode() if key is not None else b""
    path += class_segment(CLASS_ASSEMBLY) + instance_segment(config_instance)
    path += connection_point_segment(o2t_point) + connection_point_segment(t2o_point)
    if config_data:
        path += data_segment(config_data)
    return path


# --------------------------------------------------------------------------- decoding


class Segment(NamedTuple):
    """One decoded segment: ``kind`` is ``class``, ``instance``, ``member``,
    ``connection_point``, ``attribute``, ``key``, ``data`` or ``port``."""

    kind: str
    value: int
    data: bytes = b""


_KIND_NAMES: Final = {
    _CLASS: "class",
    _INSTANCE: "instance",
    _MEMBER: "member",
    _CONNECTION_POINT: "connection_point",
    _ATTRIBUTE: "attribute",
}


def _need(path: bytes | memoryview, offset: int, count: int, what: str) -> None:
    if offset + count > len(path):
        raise PathError(f"{what} at byte {offset}: needs {count} bytes, path has {len(path)}")


def decode_segments(path: bytes | bytearray | memoryview) -> list[Segment]:
    """Split a padded EPATH into segments; :class:`PathError` on anything not understood."""
    data = bytes(path)
    segments: list[Segment] = []
    offset = 0
    while offset < len(data):
        head = data[offset]
        kind = head >> 5
        if head == _KEY_SEGMENT:
            _need(data, offset, 2 + _KEY.size, "electronic key")
            if data[offset + 1] != _KEY_FORMAT:
                raise PathError(f"electronic key format {data[offset + 1]} (only 4 is known)")
            raw = data[offset + 2 : offset + 2 + _KEY.size]
            segments.append(Segment("key", _KEY_FORMAT, raw))
            offset += 2 + _KEY.size
        elif kind == 1:  # logical
            logical_type = (head >> 2) & 0x07
            fmt = head & 0x03
            name = _KIND_NAMES.get(logical_type)
            if name is None:
                raise PathError(f"logical segment type {logical_type} (0x{head:02X}) not allowed")
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
        elif kind == 0:  # port segment: 000e pppp, link (or link size + link), padded
            port = head & 0x0F
            if head & 0x10:
                _need(data, offset, 2, "port segment")
                size = data[offset + 1]
                _need(data, offset + 2, size, "port segment link")
                link = data[offset + 2 : offset + 2 + size]
                offset += 2 + size + (size % 2)
            else:
                _need(data, offset, 2, "port segment")
                link = data[offset + 1 : offset + 2]
                offset += 2
            segments.append(Segment("port", port, link))
        else:
            raise PathError(f"segment type 0x{head:02X} at byte {offset} not supported")
    return segments


@dataclass(frozen=True, slots=True)
class RequestPath:
    class_id: int
    instance: int | None
    attribute: int | None


def decode_request_path(path: bytes | bytearray | memoryview) -> RequestPath:
    """A Message Router request path: class, then optional instance and attribute."""
    class_id: int | None = None
    instance: int | None = None
    attribute: int | None = None
    for seg in decode_segments(path):
        if seg.kind == "class" and class_id is None and instance is None:
            class_id = seg.value
        elif seg.kind == "instance" and class_id is not None and instance is None:
            instance = seg.value
        elif seg.kind == "attribute" and instance is not None and attribute is None:
            attribute = seg.value
        else:
            raise PathError(f"unexpected {seg.kind} segment in a request path")
    if class_id is None:
        raise PathError("request path names no class")
    return RequestPath(class_id, instance, attribute)


@dataclass(frozen=True, slots=True)
class ConnectionPath:
    """A decoded Forward Open connection path.

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
    key: ElectronicKey | None = None
    class_id: int | None = None
    config: int | None = None
    points: list[int] = []
    config_data = b""
    ports: list[int] = []
    for seg in decode_segments(path):
        if seg.kind == "key" and key is None and class_id is None:
            key = ElectronicKey._make(_KEY.unpack(seg.data))
        elif seg.kind == "port" and class_id is None:
            ports.append(seg.value)
        elif seg.kind == "class" and class_id is None:
            class_id = seg.value
        elif seg.kind == "instance" and class_id is not None and config is None and not points:
            config = seg.value
        elif seg.kind in ("connection_point", "instance") and class_id is not None:
            points.append(seg.value)
        elif seg.kind == "data" and class_id is not None and not config_data:
            config_data = seg.data
        else:
            raise PathError(f"unexpected {seg.kind} segment in a connection path")
    if class_id is None:
        raise PathError("connection path names no class")
    return ConnectionPath(class_id, config, tuple(points), key, config_data, tuple(ports))
