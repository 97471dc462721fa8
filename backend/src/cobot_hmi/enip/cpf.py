"""Layer: enip (pure). Imports only ``cobot_hmi.enip``.

The Common Packet Format (CIP Vol 2 §2-6; docs/protocol.md): an item count
then items of (type, length, data). Sockaddr Info items (0x8000 O→T, 0x8001 T→O) carry a
``sockaddr_in`` whose fields are big-endian (network order), unlike everything else.
"""

from __future__ import annotations

import ipaddress
import struct
from enum import IntEnum
from typing import Final, NamedTuple

from cobot_hmi.enip.errors import LengthMismatchError, TruncatedError, UnexpectedItemError


class ItemType(IntEnum):
    NULL_ADDRESS = 0x0000
    LIST_IDENTITY = 0x000C
    CONNECTED_ADDRESS = 0x00A1
    CONNECTED_DATA = 0x00B1
    UNCONNECTED_DATA = 0x00B2
    SOCKADDR_O2T = 0x8000
    SOCKADDR_T2O = 0x8001
    SEQUENCED_ADDRESS = 0x8002


_COUNT: Final = struct.Struct("<H")
_ITEM: Final = struct.Struct("<HH")
MAX_ITEMS: Final = 16
"""More items than any EtherNet/IP message carries: a sign of garbage."""


class CpfItem(NamedTuple):
    type_id: int
    data: bytes


def encode_items(items: list[CpfItem] | tuple[CpfItem, ...]) -> bytes:
    parts = [_COUNT.pack(len(items))]
    for item in items:
        parts.append(_ITEM.pack(item.type_id, len(item.data)))
        parts.append(item.data)
    return b"".join(parts)


def decode_items(data: bytes | bytearray | memoryview, *, exact: bool = True) -> list[CpfItem]:
    """Decode an item list; with ``exact`` no byte may follow the last item."""
    view = memoryview(data)
    if len(view) < _COUNT.size:
        raise TruncatedError("CPF item count", _COUNT.size, len(view))
    (count,) = _COUNT.unpack_from(view)
    if count > MAX_ITEMS:
        raise UnexpectedItemError(f"CPF item count {count} exceeds {MAX_ITEMS}")
    offset = _COUNT.size
    items: list[CpfItem] = []
    for index in range(count):
        if len(view) - offset < _ITEM.size:
            raise TruncatedError(f"CPF item {index} header", _ITEM.size, len(view) - offset)
        type_id, length = _ITEM.unpack_from(view, offset)
        offset += _ITEM.size
        if len(view) - offset < length:
            raise TruncatedError(
                f"CPF item {index} (0x{type_id:04X}) data", length, len(view) - offset
            )
        items.append(CpfItem(type_id, bytes(view[offset : offset + length])))
        offset += length
    if exact and offset != len(view):
        raise LengthMismatchError(f"{len(view) - offset} bytes after the last CPF item")
    return items


def find_item(items: list[CpfItem], type_id: int) -> CpfItem | None:
    for item in items:
        if item.type_id == type_id:
            return item
    return None


# --------------------------------------------------------------------------- Sockaddr Info

_SOCKADDR: Final = struct.Struct(">hH4s8s")  # sin_family, sin_port, sin_addr, sin_zero: big-endian
SOCKADDR_SIZE: Final = _SOCKADDR.size  # 16
AF_INET: Final = 2


class Sockaddr(NamedTuple):
    """A Sockaddr Info item's address; ``host`` ``0.0.0.0`` means "the TCP peer's address"."""

    host: str
    port: int


def encode_sockaddr(addr: Sockaddr) -> bytes:
    return _SOCKADDR.pack(AF_INET, addr.port, ipaddress.IPv4Address(addr.host).packed, bytes(8))


def decode_sockaddr(data: bytes | bytearray | memoryview) -> Sockaddr:
    if len(data) != SOCKADDR_SIZE:
        raise LengthMismatchError(f"Sockaddr Info must be {SOCKADDR_SIZE} bytes, got {len(data)}")
    family, port, addr, _zero = _SOCKADDR.unpack(data)
    if family != AF_INET:
        raise UnexpectedItemError(f"Sockaddr Info family {family}, expected AF_INET (2)")
    return Sockaddr(str(ipaddress.IPv4Address(addr)), port)


def sockaddr_item(type_id: int, addr: Sockaddr) -> CpfItem:
    return CpfItem(type_id, encode_sockaddr(addr))
