"""Layer: enip (pure). Imports nothing of the project.

CIP general status codes (CIP Vol 1 Appendix B) and the Connection Manager's extended status
codes (Vol 1 §3-5; docs/protocol.md "Refusals"), with their words, and :func:`describe`, which
turns a reply's statuses into a sentence, including the size a target expected for 0x0127 /
0x0128 / 0x0109.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Final


class GeneralStatus(IntEnum):
    SUCCESS = 0x00
    CONNECTION_FAILURE = 0x01
    RESOURCE_UNAVAILABLE = 0x02
    INVALID_PARAMETER_VALUE = 0x03
    PATH_SEGMENT_ERROR = 0x04
    PATH_DESTINATION_UNKNOWN = 0x05
    PARTIAL_TRANSFER = 0x06
    CONNECTION_LOST = 0x07
    SERVICE_NOT_SUPPORTED = 0x08
    INVALID_ATTRIBUTE_VALUE = 0x09
    ATTRIBUTE_LIST_ERROR = 0x0A
    ALREADY_IN_REQUESTED_STATE = 0x0B
    OBJECT_STATE_CONFLICT = 0x0C
    OBJECT_ALREADY_EXISTS = 0x0D
    ATTRIBUTE_NOT_SETTABLE = 0x0E
    PRIVILEGE_VIOLATION = 0x0F
    DEVICE_STATE_CONFLICT = 0x10
    REPLY_DATA_TOO_LARGE = 0x11
    FRAGMENTATION_OF_PRIMITIVE = 0x12
    NOT_ENOUGH_DATA = 0x13
    ATTRIBUTE_NOT_SUPPORTED = 0x14
    TOO_MUCH_DATA = 0x15
    OBJECT_DOES_NOT_EXIST = 0x16
    NO_FRAGMENTATION_IN_PROGRESS = 0x17
    NO_STORED_ATTRIBUTE_DATA = 0x18
    STORE_OPERATION_FAILURE = 0x19
    REQUEST_TOO_LARGE = 0x1A
    RESPONSE_TOO_LARGE = 0x1B
    MISSING_ATTRIBUTE_LIST_ENTRY = 0x1C
    INVALID_ATTRIBUTE_VALUE_LIST = 0x1D
    EMBEDDED_SERVICE_ERROR = 0x1E
    VENDOR_SPECIFIC = 0x1F
    INVALID_PARAMETER = 0x20
    WRITE_ONCE_ALREADY_WRITTEN = 0x21
    INVALID_REPLY_RECEIVED = 0x22
    BUFFER_OVERFLOW = 0x23
    INVALID_MESSAGE_FORMAT = 0x24
    KEY_FAILURE_IN_PATH = 0x25
    PATH_SIZE_INVALID = 0x26
    UNEXPECTED_ATTRIBUTE_IN_LIST = 0x27
    INVALID_MEMBER_ID = 0x28
    MEMBER_NOT_SETTABLE = 0x29
    ATTRIBUTE_NOT_GETTABLE = 0x2C


GENERAL_STATUS_WORDS: Final[dict[int, str]] = {
    0x00: "success",
    0x01: "connection failure",
    0x02: "resource unavailable",
    0x03: "invalid parameter value",
    0x04: "path segment error",
    0x05: "path destination unknown",
    0x06: "partial transfer",
    0x07: "connection lost",
    0x08: "service not supported",
    0x09: "invalid attribute value",
    0x0A: "attribute list error",
    0x0B: "already in requested mode/state",
    0x0C: "object state conflict",
    0x0D: "object already exists",
    0x0E: "attribute not settable",
    0x0F: "privilege violation",
    0x10: "device state conflict",
    0x11: "reply data too large",
    0x12: "fragmentation of a primitive value",
    0x13: "not enough data",
    0x14: "attribute not supported",
    0x15: "too much data",
    0x16: "object does not exist",
    0x17: "service fragmentation sequence not in progress",
    0x18: "no stored attribute data",
    0x19: "store operation failure",
    0x1A: "routing failure, request packet too large",
    0x1B: "routing failure, response packet too large",
    0x1C: "missing attribute list entry data",
    0x1D: "invalid attribute value list",
    0x1E: "embedded service error",
    0x1F: "vendor specific error",
    0x20: "invalid parameter",
    0x21: "write-once value or medium already written",
    0x22: "invalid reply received",
    0x23: "buffer overflow",
    0x24: "invalid message format",
    0x25: "key failure in path",
    0x26: "path size invalid",
    0x27: "unexpected attribute in list",
    0x28: "invalid member ID",
    0x29: "member not settable",
    0x2C: "attribute not gettable",
}


class ExtendedStatus(IntEnum):
    """Connection Manager extended status codes (with general status 0x01)."""

    CONNECTION_IN_USE = 0x0100
    TRANSPORT_NOT_SUPPORTED = 0x0103
    OWNERSHIP_CONFLICT = 0x0106
    CONNECTION_NOT_FOUND = 0x0107
    INVALID_NETWORK_PARAMETER = 0x0108
    INVALID_CONNECTION_SIZE = 0x0109
    RPI_NOT_SUPPORTED = 0x0111
    RPI_NOT_ACCEPTABLE = 0x0112
    OUT_OF_CONNECTIONS = 0x0113
    VENDOR_PRODUCT_MISMATCH = 0x0114
    DEVICE_TYPE_MISMATCH = 0x0115
    REVISION_MISMATCH = 0x0116
    INVALID_APPLICATION_PATH = 0x0117
    INVALID_CONFIGURATION_PATH = 0x0118
    NON_LISTEN_ONLY_NOT_OPENED = 0x0119
    INVALID_O2T_CONNECTION_TYPE = 0x0123
    INVALID_T2O_CONNECTION_TYPE = 0x0124
    INVALID_CONFIGURATION_SIZE = 0x0126
    INVALID_O2T_SIZE = 0x0127
    INVALID_T2O_SIZE = 0x0128
    TIMEOUT_MULTIPLIER_NOT_ACCEPTABLE = 0x0133
    CONNECTION_TIMED_OUT = 0x0203
    UNCONNECTED_REQUEST_TIMED_OUT = 0x0204
    UNCONNECTED_SEND_PARAMETER_ERROR = 0x0205
    INVALID_SEGMENT_IN_PATH = 0x0315


EXTENDED_STATUS_WORDS: Final[dict[int, str]] = {
    0x0100: "connection in use or duplicate Forward Open",
    0x0103: "transport class and trigger combination not supported",
    0x0106: "ownership conflict (another originator owns the outputs)",
    0x0107: "target connection not found",
    0x0108: "invalid network connection parameter",
    0x0109: "invalid connection size",
    0x0110: "target for connection not configured",
    0x0111: "RPI not supported",
    0x0112: "RPI value(s) not acceptable",
    0x0113: "out of connections",
    0x0114: "vendor ID or product code mismatch (electronic key)",
    0x0115: "device type mismatch (electronic key)",
    0x0116: "revision mismatch (electronic key)",
    0x0117: "invalid produced or consumed application path (unknown connection point)",
    0x0118: "invalid or inconsistent configuration application path",
    0x0119: "non-listen-only connection not opened",
    0x011A: "target object out of connections",
    0x011B: "RPI is smaller than the production inhibit time",
    0x011C: "transport class not supported",
    0x011D: "production trigger not supported",
    0x011E: "direction not supported",
    0x011F: "invalid O→T fixed/variable flag",
    0x0120: "invalid T→O fixed/variable flag",
    0x0121: "invalid O→T priority",
    0x0122: "invalid T→O priority",
    0x0123: "invalid O→T connection type",
    0x0124: "invalid T→O connection type",
    0x0125: "invalid O→T redundant owner flag",
    0x0126: "invalid configuration size",
    0x0127: "invalid O→T connection size",
    0x0128: "invalid T→O connection size",
    0x0129: "invalid configuration application path",
    0x012A: "invalid consuming application path",
    0x012B: "invalid producing application path",
    0x012F: "inconsistent application path combination",
    0x0132: "null Forward Open not supported",
    0x0133: "connection timeout multiplier not acceptable",
    0x0203: "connection timed out",
    0x0204: "unconnected request timed out",
    0x0205: "parameter error in unconnected request",
    0x0206: "message too large for unconnected send",
    0x0301: "no buffer memory available",
    0x0302: "network bandwidth not available",
    0x0303: "no consumed connection ID filter available",
    0x0311: "port not available",
    0x0312: "link address not valid",
    0x0315: "invalid segment in connection path",
    0x0316: "error in Forward Close connection path",
    0x031C: "miscellaneous",
    0x0800: "network link offline",
    0x0810: "no target application data available",
    0x0811: "no originator application data available",
}

_SIZE_STATUSES: Final = frozenset({0x0109, 0x0126, 0x0127, 0x0128})
"""Extended statuses after which a well-behaved target puts the size it expected."""


def general_words(status: int) -> str:
    return GENERAL_STATUS_WORDS.get(status, f"unknown general status 0x{status:02X}")


def extended_words(status: int) -> str:
    return EXTENDED_STATUS_WORDS.get(status, f"unknown extended status 0x{status:04X}")


def expected_size(extended: tuple[int, ...]) -> int | None:
    """The size a target expected, from the word after a size-related extended status."""
    if len(extended) >= 2 and extended[0] in _SIZE_STATUSES:
        return extended[1]
    return None


def describe(general: int, extended: tuple[int, ...] = ()) -> str:
    """A reply's statuses in words, e.g. ``connection failure (0x01): invalid O→T connection
    size (0x0127); the target expected 26 bytes``."""
    text = f"{general_words(general)} (0x{general:02X})"
    if general == GeneralStatus.CONNECTION_FAILURE and extended:
        text += f": {extended_words(extended[0])} (0x{extended[0]:04X})"
        size = expected_size(extended)
        if size is not None:
            text += f"; the target expected {size} bytes"
        elif len(extended) > 1:
            text += "; additional status " + " ".join(f"0x{w:04X}" for w in extended[1:])
    elif extended:
        text += "; additional status " + " ".join(f"0x{w:04X}" for w in extended)
    return text
