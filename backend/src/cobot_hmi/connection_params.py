"""Layer: protocol (pure, beside ``cobot_hmi.enip``). Imports the layout and ``cobot_hmi.enip``;
never the emulator, the scanner, the service or any I/O.

The one declaration of each class 1 connection setting: its default, unit, bounds and help
text. The emulator (``emulator.target_settings.TargetSettings``), the scanner
(``scanner.originator.OriginatorSettings``) and the service (``service.service_settings``,
where each becomes a typed, bounded setting with its flag and ``COBOT_HMI_*`` variable) take
them from here, so a default or a limit is changed in one place.

The bounds are what the protocol can carry (Forward Open, CIP Vol 1 §3-5.4): a real robot may
accept less, and says so by refusing the Forward Open with an extended status.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final, Generic, TypeVar

from cobot_hmi.enip.encapsulation import ENIP_TCP_PORT as ENIP_TCP_PORT_NUMBER
from cobot_hmi.enip.encapsulation import ENIP_UDP_PORT as ENIP_UDP_PORT_NUMBER
from cobot_hmi.layout import CONNECTION_POINTS, O2T_ASSEMBLY, T2O_ASSEMBLY

N = TypeVar("N", int, float)


@dataclass(frozen=True, slots=True)
class ConnectionParam(Generic[N]):
    """One connection setting: default, inclusive bounds, unit and what it means."""

    default: N
    help: str
    minimum: N
    maximum: N
    unit: str = ""

    def check(self, name: str, value: N) -> N:
        """``value`` if within the bounds; else ``ValueError`` naming ``name`` and the range."""
        if not self.minimum <= value <= self.maximum:
            raise ValueError(f"{name}: {self.range_text()}, got {value}")
        return value

    def range_text(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.minimum}–{self.maximum}{unit}"


ENIP_TCP_PORT: Final = ConnectionParam(
    ENIP_TCP_PORT_NUMBER,
    "EtherNet/IP TCP port of the target (encapsulation, CIP Vol 2 §2-2); 0 = any free port",
    minimum=0,
    maximum=65535,
)
CLASS1_UDP_PORT: Final = ConnectionParam(
    ENIP_UDP_PORT_NUMBER,
    'UDP port of class 1 (implicit) I/O (docs/protocol.md, "Cyclic packets, UDP 2222")',
    minimum=0,
    maximum=65535,
)
RPI_US: Final = ConnectionParam(
    10_000,
    "requested packet interval (RPI) of the cyclic connection, both directions",
    minimum=1_000,
    maximum=10_000_000,
    unit="µs",
)
TIMEOUT_MULTIPLIER: Final = ConnectionParam(
    2,
    "connection timeout multiplier: a side declares the connection lost after "
    "RPI × (4 << multiplier) without a packet (CIP Vol 1 §3-5.4.1)",
    minimum=0,
    maximum=7,
)
_INSTANCE_MAX: Final = 0xFFFF
"""An assembly instance in a 16-bit logical segment (CIP Vol 1 §C-1.4.2)."""
CONFIG_INSTANCE: Final = ConnectionParam(
    CONNECTION_POINTS.configuration,
    "configuration assembly instance of the connection path",
    minimum=1,
    maximum=_INSTANCE_MAX,
)
O2T_INSTANCE: Final = ConnectionParam(
    CONNECTION_POINTS.o2t,
    "O→T (command, PLC→robot) assembly instance",
    minimum=1,
    maximum=_INSTANCE_MAX,
)
T2O_INSTANCE: Final = ConnectionParam(
    CONNECTION_POINTS.t2o,
    "T→O (robot frame, robot→PLC) assembly instance",
    minimum=1,
    maximum=_INSTANCE_MAX,
)
HEARTBEAT_INSTANCE: Final = ConnectionParam(
    CONNECTION_POINTS.input_only,
    "input-only heartbeat connection point (O→T of an input-only connection)",
    minimum=1,
    maximum=_INSTANCE_MAX,
)
LISTEN_ONLY_INSTANCE: Final = ConnectionParam(
    CONNECTION_POINTS.listen_only,
    "listen-only heartbeat connection point",
    minimum=1,
    maximum=_INSTANCE_MAX,
)
# Connection sizes are 16-bit in a Large Forward Open; the header (2-byte sequence count, and
# the 4-byte run/idle header on O→T) counts against them (CIP Vol 1 §3-5.4.1).
O2T_SIZE: Final = ConnectionParam(
    O2T_ASSEMBLY.size_bytes,
    "O→T data size (without sequence count and run/idle header)",
    minimum=0,
    maximum=0xFFFF - 6,
    unit="bytes",
)
T2O_SIZE: Final = ConnectionParam(
    T2O_ASSEMBLY.size_bytes,
    "T→O data size (without sequence count)",
    minimum=0,
    maximum=0xFFFF - 2,
    unit="bytes",
)
