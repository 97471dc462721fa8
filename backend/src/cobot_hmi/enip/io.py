"""Layer: enip (pure). Imports only ``cobot_hmi.enip``.

The class 1 (cyclic I/O) UDP packet (CIP Vol 2 §3-4; docs/protocol.md): a CPF of exactly two
items, Sequenced Address 0x8002 (connection ID, encapsulation sequence number) and Connected
Data 0x00B1 (CIP sequence count, the 32-bit run/idle header where the direction has one, then
the data). This runs for every datagram, so it uses precompiled structs and returns plain
tuples; it still never lets a ``struct.error`` escape.
"""

from __future__ import annotations

import struct
from typing import Final, NamedTuple

from cobot_hmi.enip.cpf import ItemType
from cobot_hmi.enip.errors import (
    EnipError,
    LengthMismatchError,
    TruncatedError,
    UnexpectedItemError,
)

_PREFIX: Final = struct.Struct("<HHHIIHH")  # count, 0x8002, 8, conn id, encap seq, 0x00B1, length
PREFIX_SIZE: Final = _PREFIX.size  # 18
ENCAP_SEQ_OFFSET: Final = 10
"""Where the encapsulation sequence number (UDINT) sits: after the item count, the Sequenced
Address item's type and length, and the connection ID."""
CIP_SEQ_OFFSET: Final = PREFIX_SIZE
"""Where the CIP sequence count (UINT) sits, in a packet that has one: first in the Connected
Data item."""
_WITH_HEADER: Final = struct.Struct("<HHHIIHHHI")
_WITHOUT_HEADER: Final = struct.Struct("<HHHIIHHH")
_SEQ: Final = struct.Struct("<H")
_PREFIX_AND_SEQ: Final = struct.Struct("<HHHIIHHH")
"""The prefix and the CIP sequence count in one read: every T→O frame has both (the cyclic
thread decodes 100 a second per robot)."""
_new_packet: Final = tuple.__new__
"""``IoPacket`` without its Python-level ``__new__`` (half the cost of a decode)."""
_RUN_IDLE: Final = struct.Struct("<I")

RUN_BIT: Final = 0x0000_0001
"""Bit 0 of the run/idle header: 1 = run, 0 = idle."""
SEQ_ADDR: Final = int(ItemType.SEQUENCED_ADDRESS)
CONNECTED_DATA: Final = int(ItemType.CONNECTED_DATA)
MAX_DATAGRAM: Final = 1500
"""Class 1 packets fit one Ethernet frame; anything larger is not a packet of ours."""


class IoPacket(NamedTuple):
    connection_id: int
    encap_seq: int
    cip_seq: int | None
    """``None`` for a Connected Data item without a sequence count (a zero-size heartbeat)."""
    payload: bytes
    """After the CIP sequence count: the run/idle header (if any) and the data."""


def encode_io(
    connection_id: int,
    encap_seq: int,
    cip_seq: int,
    data: bytes,
    run_idle: int | None = None,
) -> bytes:
    """One class 1 datagram; ``run_idle`` adds the 32-bit header (1 = run, 0 = idle)."""
    if run_idle is None:
        return (
            _WITHOUT_HEADER.pack(
                2,
                SEQ_ADDR,
                8,
                connection_id,
                encap_seq & 0xFFFFFFFF,
                CONNECTED_DATA,
                2 + len(data),
                cip_seq & 0xFFFF,
            )
            + data
        )
    return (
        _WITH_HEADER.pack(
            2,
            SEQ_ADDR,
            8,
            connection_id,
            encap_seq & 0xFFFFFFFF,
            CONNECTED_DATA,
            6 + len(data),
            cip_seq & 0xFFFF,
            run_idle,
        )
        + data
    )


def encode_heartbeat(connection_id: int, encap_seq: int) -> bytes:
    """A Connected Data item with nothing in it (a zero-size O→T connection)."""
    return _PREFIX.pack(2, SEQ_ADDR, 8, connection_id, encap_seq & 0xFFFFFFFF, CONNECTED_DATA, 0)


def decode_io(data: bytes | bytearray | memoryview) -> IoPacket:
    size = len(data)
    if size < PREFIX_SIZE:
        raise TruncatedError("class 1 packet", PREFIX_SIZE, size)
    if size > MAX_DATAGRAM:
        raise LengthMismatchError(f"class 1 packet of {size} bytes exceeds {MAX_DATAGRAM}")
    if size >= PREFIX_SIZE + 2:
        fields = _PREFIX_AND_SEQ.unpack_from(data)
        count, addr_type, addr_len, conn_id, encap_seq, data_type, length, cip_seq = fields
    else:
        count, addr_type, addr_len, conn_id, encap_seq, data_type, length = _PREFIX.unpack_from(
            data
        )
        cip_seq = None
    if count != 2:
        raise UnexpectedItemError(f"class 1 packet with {count} CPF items, expected 2")
    if addr_type != SEQ_ADDR or addr_len != 8:
        raise UnexpectedItemError(
            f"class 1 packet address item 0x{addr_type:04X} length {addr_len}, "
            "expected Sequenced Address 0x8002 length 8"
        )
    if data_type != CONNECTED_DATA:
        raise UnexpectedItemError(
            f"class 1 packet data item 0x{data_type:04X}, expected Connected Data 0x00B1"
        )
    if length != size - PREFIX_SIZE:
        raise LengthMismatchError(
            f"Connected Data length says {length} bytes, {size - PREFIX_SIZE} follow"
        )
    if length == 0:
        return IoPacket(conn_id, encap_seq, None, b"")
    if length == 1:
        raise TruncatedError("CIP sequence count", 2, 1)
    packet: IoPacket = _new_packet(
        IoPacket, (conn_id, encap_seq, cip_seq, bytes(data[PREFIX_SIZE + 2 :]))
    )
    return packet


def split_run_idle(payload: bytes) -> tuple[bool, bytes]:
    """(run, data) from a payload that starts with the 32-bit run/idle header."""
    if len(payload) < 4:
        raise TruncatedError("run/idle header", 4, len(payload))
    (header,) = _RUN_IDLE.unpack_from(payload)
    return bool(header & RUN_BIT), payload[4:]


def seq16_newer(seq: int, last: int) -> int:
    """How far ``seq`` is ahead of ``last`` in 16-bit wrapping arithmetic: > 0 newer, 0 the
    same, < 0 older (stale)."""
    diff = (seq - last) & 0xFFFF
    return diff - 0x10000 if diff >= 0x8000 else diff


def seq32_newer(seq: int, last: int) -> int:
    """As :func:`seq16_newer` for the 32-bit encapsulation sequence number."""
    diff = (seq - last) & 0xFFFFFFFF
    return diff - 0x100000000 if diff >= 0x80000000 else diff


__all__ = [
    "MAX_DATAGRAM",
    "RUN_BIT",
    "EnipError",
    "IoPacket",
    "decode_io",
    "encode_heartbeat",
    "encode_io",
    "seq16_newer",
    "seq32_newer",
    "split_run_idle",
]
