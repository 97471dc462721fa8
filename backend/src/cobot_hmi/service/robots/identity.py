"""Layer: service. A robot's identity: what its CIP Identity object says (Vol 1 §5A-2), read with
an explicit ListIdentity over the robot's TCP port (CIP Vol 2 §2-4.2) after each connection comes
up, on the web loop (never on the cyclic thread). A robot that does not answer it keeps the
identity it had (``None`` until one is read)."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Final

from cobot_hmi.enip.errors import EnipError
from cobot_hmi.enip.identity import IdentityInfo
from cobot_hmi.scanner.session import EnipSession, SessionError

log = logging.getLogger(__name__)

IDENTITY_TIMEOUT_S: Final = 3.0


@dataclass(frozen=True, slots=True)
class RobotIdentity:
    """What the robot's CIP Identity object says (Vol 1 §5A-2), read by ListIdentity."""

    vendor_id: int
    device_type: int
    product_code: int
    revision: str
    """major.minor"""
    serial_number: int
    product_name: str

    @classmethod
    def from_info(cls, info: IdentityInfo) -> RobotIdentity:
        return cls(
            vendor_id=info.vendor_id,
            device_type=info.device_type,
            product_code=info.product_code,
            revision=info.revision,
            serial_number=info.serial_number,
            product_name=info.product_name,
        )

    def to_json(self) -> dict[str, object]:
        return {
            "vendor_id": self.vendor_id,
            "device_type": self.device_type,
            "product_code": self.product_code,
            "revision": self.revision,
            "serial_number": self.serial_number,
            "product_name": self.product_name,
        }


async def read_identity(
    host: str, tcp_port: int, timeout_s: float = IDENTITY_TIMEOUT_S
) -> RobotIdentity:
    """ListIdentity over TCP (a session of its own); ``OSError``/``SessionError``/``EnipError``."""
    session = EnipSession(host, tcp_port, timeout_s)
    try:
        await session.open()
        return RobotIdentity.from_info(await session.list_identity())
    finally:
        await session.close()


class IdentityReader:
    """One robot's identity: the last one read (``identity``), read again by ``read``."""

    def __init__(
        self, name: str, host: str, tcp_port: int, timeout_s: float = IDENTITY_TIMEOUT_S
    ) -> None:
        self.name = name
        self.host = host
        self.tcp_port = tcp_port
        self.timeout_s = timeout_s
        self.identity: RobotIdentity | None = None
        """The last identity read (``None``: none yet)."""

    async def read(self) -> None:
        """Read the identity once; a robot that does not answer keeps the one it had."""
        try:
            identity = await read_identity(self.host, self.tcp_port, self.timeout_s)
        except (OSError, SessionError, EnipError, TimeoutError) as error:
            log.info("%s: no identity (ListIdentity): %s", self.name, error)
            return
        if identity != self.identity:
            log.info("%s: %s, revision %s", self.name, identity.product_name, identity.revision)
        self.identity = identity
