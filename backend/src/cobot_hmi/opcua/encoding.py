"""Layer: OPC UA. asyncua's binary encoding of DataValues and data change notifications, fast.

A historian subscribed to every variable of a 32-robot cell is sent some 4 000 notifications a
second, and asyncua encodes each through its generic structure encoder: a closure per field,
``getattr`` by name, the optional fields' mask found by walking them, a list joined per
structure, for a MonitoredItemNotification and again for its DataValue and StatusCode (about
6 µs a notification, the most of the OPC UA thread's time after the writes themselves,
bench/fanout). This module gives asyncua's encoder two fast paths, installed into
``asyncua.ua.ua_binary`` once (``install``):

- a DataValue without picoseconds: the mask byte, then its Value (a scalar of a fixed-size
  type in one ``pack``, any other by asyncua's own ``variant_to_binary``), its StatusCode's 32
  bits, and its timestamps by asyncua's own ``datetime_to_win_epoch`` (OPC 10000-6 §5.2.2.17:
  fields in the mask's order);
- a MonitoredItemNotification: its ClientHandle's 32 bits, then its DataValue as above.

Every other DataValue (one with picoseconds: asyncua writes the server timestamp before the
source picoseconds, its own order, kept by using its encoder) and every other structure goes
through asyncua's encoder as before. The bytes are asyncua's: test_opcua_encoding compares them
with its encoder's for any DataValue Hypothesis makes, and decodes them with its decoder.

Imports asyncua only.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Callable
from typing import Any, Final

from asyncua import ua
from asyncua.ua import ua_binary

_UINT32: Final = struct.Struct("<I")
_INT64: Final = struct.Struct("<q")

_SCALARS: Final[dict[ua.VariantType, struct.Struct]] = {
    variant_type: struct.Struct(
        "<B" + getattr(ua_binary.Primitives1, variant_type.name).format.lstrip("<")
    )
    for variant_type in (
        ua.VariantType.Boolean,
        ua.VariantType.SByte,
        ua.VariantType.Byte,
        ua.VariantType.Int16,
        ua.VariantType.UInt16,
        ua.VariantType.Int32,
        ua.VariantType.UInt32,
        ua.VariantType.Int64,
        ua.VariantType.UInt64,
        ua.VariantType.Float,
        ua.VariantType.Double,
    )
}
"""The encoding byte and the value of a scalar Variant of a fixed-size type, in asyncua's own
formats (``Primitives1``): one ``pack``."""

_VALUE: Final = 0x01
_STATUS: Final = 0x02
_SOURCE_TIME: Final = 0x04
_SERVER_TIME: Final = 0x08

_asyncua_variant: Final[Callable[[ua.Variant], bytes]] = ua_binary.variant_to_binary

ASYNCUA_DATACLASS_SERIALIZER: Final[Callable[[type], Callable[[Any], bytes]]] = (
    ua_binary.create_dataclass_serializer
)
"""asyncua's own (kept before ``install``: the reference the tests compare with)."""


def asyncua_encoding(dataclazz: type, value: Any) -> bytes:
    """``value`` encoded by asyncua's own structure encoder, without the fast paths."""
    return ASYNCUA_DATACLASS_SERIALIZER(dataclazz)(value)


def encode_variant(variant: ua.Variant) -> bytes:
    """A Variant as asyncua's ``variant_to_binary`` encodes it: a scalar of a fixed-size type in
    one ``pack`` (its encoding byte is its type's id), anything else by asyncua's own."""
    scalar = _SCALARS.get(variant.VariantType)
    value = variant.Value
    if scalar is None or variant.is_array or isinstance(value, list | tuple):
        return _asyncua_variant(variant)
    try:
        return scalar.pack(variant.VariantType.value, value)
    except (struct.error, TypeError, OverflowError):  # asyncua's own says what does not fit
        return _asyncua_variant(variant)


def encode_data_value(value: ua.DataValue) -> bytes:
    """A DataValue as asyncua encodes it (see the module docstring)."""
    if value.SourcePicoseconds is not None or value.ServerPicoseconds is not None:
        return asyncua_encoding(ua.DataValue, value)
    variant = value.Value
    status = value.StatusCode
    source = value.SourceTimestamp
    server = value.ServerTimestamp
    mask = 0
    parts: list[bytes] = [b""]
    if variant is not None:
        mask |= _VALUE
        parts.append(encode_variant(variant))
    if status is not None:
        mask |= _STATUS
        parts.append(_UINT32.pack(status.value))
    if source is not None:
        mask |= _SOURCE_TIME
        parts.append(_INT64.pack(ua.datetime_to_win_epoch(source)))
    if server is not None:
        mask |= _SERVER_TIME
        parts.append(_INT64.pack(ua.datetime_to_win_epoch(server)))
    parts[0] = bytes((mask,))
    return b"".join(parts)


def encode_monitored_item_notification(notification: ua.MonitoredItemNotification) -> bytes:
    """A MonitoredItemNotification as asyncua encodes it: ClientHandle, then the DataValue."""
    return _UINT32.pack(notification.ClientHandle) + encode_data_value(notification.Value)


_FAST: Final[dict[type, Callable[[Any], bytes]]] = {
    ua.DataValue: encode_data_value,
    ua.MonitoredItemNotification: encode_monitored_item_notification,
}


@functools.cache
def _dataclass_serializer(dataclazz: type) -> Callable[[Any], bytes]:
    """asyncua's ``create_dataclass_serializer`` with the fast paths (cached as it is)."""
    return _FAST.get(dataclazz) or ASYNCUA_DATACLASS_SERIALIZER(dataclazz)


def install() -> None:
    """Put the fast paths into asyncua's encoder (idempotent). asyncua looks its structure
    encoder up by name at every use and caches what it builds from it: the caches are emptied
    so that nothing built before keeps the slow path."""
    if ua_binary.create_dataclass_serializer is _dataclass_serializer:
        return
    ua_binary.create_dataclass_serializer = _dataclass_serializer
    ASYNCUA_DATACLASS_SERIALIZER.cache_clear()  # type: ignore[attr-defined]
    ua_binary.create_type_serializer.cache_clear()
    ua_binary.create_list_serializer.cache_clear()
    ua_binary.create_uatype_serializer.cache_clear()
