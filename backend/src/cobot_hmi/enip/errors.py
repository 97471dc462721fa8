"""Layer: enip (pure). Imports nothing of the project.

The typed errors every EtherNet/IP decoder raises on malformed bytes. A caller catches
``EnipError`` once and counts the packet as malformed; nothing lower level escapes.
"""

from __future__ import annotations


class EnipError(ValueError):
    """Bytes that do not form the EtherNet/IP or CIP structure they were decoded as."""


class TruncatedError(EnipError):
    """Fewer bytes than the structure (or its own length field) needs."""

    def __init__(self, what: str, needed: int, available: int) -> None:
        super().__init__(f"{what}: needs {needed} bytes, only {available} available")
        self.needed = needed
        self.available = available


class LengthMismatchError(EnipError):
    """A length field that disagrees with the bytes that carry it."""


class UnexpectedItemError(EnipError):
    """A Common Packet Format item of a type, or in a place, the structure does not allow."""


class PathError(EnipError):
    """An EPATH that cannot be decoded, or has a segment this use does not allow.

    The target answers it with extended status 0x0315 (invalid segment in connection path)
    in a Forward Open, or general status 0x04 (path segment error) in an explicit request.
    """
