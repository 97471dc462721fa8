"""Layer: enip (pure). Imports only ``cobot_hmi.enip``.

The Identity object (class 0x01, instance 1): attributes 1–7 as Get_Attribute_Single and
Get_Attributes_All return them, and the CIP Identity item (0x000C) of a ListIdentity reply,
which adds the encapsulation protocol version, a big-endian sockaddr and the state.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum
from typing import Final

from cobot_hmi.enip.cpf import SOCKADDR_SIZE, Sockaddr, decode_sockaddr, encode_sockaddr
from cobot_hmi.enip.errors import EnipError, LengthMismatchError, TruncatedError


class IdentityAttribute(IntEnum):
    VENDOR_ID = 1
    DEVICE_TYPE = 2
    PRODUCT_CODE = 3
    REVISION = 4
    STATUS = 5
    SERIAL_NUMBER = 6
    PRODUCT_NAME = 7


_FIXED: Final = struct.Struct("<HHHBBHI")  # attributes 1–6


@dataclass(frozen=True, slots=True)
class IdentityInfo:
    vendor_id: int
    device_type: int
    product_code: int
    revision_major: int
    revision_minor: int
    status: int
    serial_number: int
    product_name: str
    state: int = 3  # "operational" in the ListIdentity item

    @property
    def revision(self) -> str:
        return f"{self.revision_major}.{self.revision_minor:03d}"

    def _name_bytes(self) -> bytes:
        name = self.product_name.encode("ascii", "replace")[:32]
        return bytes((len(name),)) + name

    def encode_attribute(self, attribute: int) -> bytes:
        """One attribute's value; ``KeyError`` for an attribute the object does not have."""
        fixed = _FIXED.pack(
            self.vendor_id,
            self.device_type,
            self.product_code,
            self.revision_major,
            self.revision_minor,
            self.status,
            self.serial_number,
        )
        slices = {1: (0, 2), 2: (2, 4), 3: (4, 6), 4: (6, 8), 5: (8, 10), 6: (10, 14)}
        if attribute in slices:
            start, end = slices[attribute]
            return fixed[start:end]
        if attribute == IdentityAttribute.PRODUCT_NAME:
            return self._name_bytes()
        raise KeyError(attribute)

    def encode_attributes_all(self) -> bytes:
        """Attributes 1–7 in order, as Get_Attributes_All returns them."""
        return (
            _FIXED.pack(
                self.vendor_id,
                self.device_type,
                self.product_code,
                self.revision_major,
                self.revision_minor,
                self.status,
                self.serial_number,
            )
            + self._name_bytes()
        )

    def encode_list_identity_item(self, address: Sockaddr, protocol_version: int = 1) -> bytes:
        """The data of the CIP Identity item (0x000C) in a ListIdentity reply."""
        return (
            struct.pack("<H", protocol_version)
            + encode_sockaddr(address)
            + self.encode_attributes_all()
            + bytes((self.state,))
        )


def _decode_fixed_and_name(raw: bytes, offset: int, what: str) -> tuple[tuple[int, ...], str, int]:
    if len(raw) < offset + _FIXED.size + 1:
        raise TruncatedError(what, offset + _FIXED.size + 1, len(raw))
    fixed = _FIXED.unpack_from(raw, offset)
    name_len = raw[offset + _FIXED.size]
    start = offset + _FIXED.size + 1
    if len(raw) < start + name_len:
        raise TruncatedError(f"{what} product name", start + name_len, len(raw))
    try:
        name = raw[start : start + name_len].decode("ascii")
    except UnicodeDecodeError:
        raise EnipError(f"{what}: product name is not ASCII") from None
    return fixed, name, start + name_len


def _identity(fixed: tuple[int, ...], name: str, state: int) -> IdentityInfo:
    vendor, device_type, product_code, major, minor, status, serial = fixed
    return IdentityInfo(
        vendor, device_type, product_code, major, minor, status, serial, name, state
    )


def decode_attributes_all(data: bytes | bytearray | memoryview) -> IdentityInfo:
    raw = bytes(data)
    fixed, name, _end = _decode_fixed_and_name(raw, 0, "Identity Get_Attributes_All")
    return _identity(fixed, name, 3)


def decode_list_identity_item(
    data: bytes | bytearray | memoryview,
) -> tuple[IdentityInfo, Sockaddr]:
    """(identity, the sockaddr the target announced) from a CIP Identity item's data."""
    raw = bytes(data)
    head = 2 + SOCKADDR_SIZE
    if len(raw) < head:
        raise TruncatedError("ListIdentity item", head, len(raw))
    address = decode_sockaddr(raw[2:head])
    fixed, name, end = _decode_fixed_and_name(raw, head, "ListIdentity item")
    if len(raw) != end + 1:
        raise LengthMismatchError(
            f"ListIdentity item: {len(raw) - end} bytes after the name, "
            "expected the state byte only"
        )
    return _identity(fixed, name, raw[end]), address
