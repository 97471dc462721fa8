"""Layer: emulator. Imports ``cobot_hmi.connection_params`` and ``cobot_hmi.enip``.

Everything about the target that a user or a test may configure: addresses, the assembly
instances and sizes of issue 3, the RPI range, the connection limit, the idle behaviour and
the identity the target reports.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cobot_hmi import connection_params as cp
from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.enip.encapsulation import ENIP_TCP_PORT, ENIP_UDP_PORT
from cobot_hmi.enip.identity import IdentityInfo

DOOSAN_VENDOR_ID = 1573
"""Doosan Robotics' vendor ID in ODVA's list of vendor IDs: the robots the emulator stands in
for identify with it, so a scanner matching EDS files by vendor treats the emulator as the
robot."""


def default_identity(model: str = "M1013", vendor_id: int = DOOSAN_VENDOR_ID) -> IdentityInfo:
    """The identity of the emulated ``model`` (``M1013``, ``M0609``): Doosan's vendor ID unless
    ``vendor_id`` says otherwise, product code and serial number from the model's digits, so
    each arm of a cell says which it is."""
    # The device type, product code and revision are placeholders: a real controller's come
    # from its EDS file.
    if not 0 <= vendor_id <= 0xFFFF:
        raise ValueError(f"vendor_id must be 0..65535 (a UINT), got {vendor_id}")
    digits = model.lstrip("M")
    return IdentityInfo(
        vendor_id=vendor_id,
        device_type=0x2B,  # generic device (keyable)
        product_code=int(digits),
        revision_major=2,
        revision_minor=12,
        status=0x0030,
        serial_number=0x2013_0000 + int(digits, 16),
        product_name=f"Doosan {model} (emulated)",
    )


@dataclass(frozen=True)
class TargetSettings:
    """The connection settings' defaults and the RPI range come from their one declaration
    (``cobot_hmi.connection_params``), shared with the service and the scanner."""

    host: str = "127.0.0.2"
    tcp_port: int = cp.ENIP_TCP_PORT.default
    """0 picks a free port (tests), read back from ``Target.tcp_port``."""
    udp_port: int = cp.CLASS1_UDP_PORT.default
    config_instance: int = cp.CONFIG_INSTANCE.default
    o2t_instance: int = cp.O2T_INSTANCE.default
    t2o_instance: int = cp.T2O_INSTANCE.default
    input_only_instance: int = cp.HEARTBEAT_INSTANCE.default
    listen_only_instance: int = cp.LISTEN_ONLY_INSTANCE.default
    o2t_size: int = cp.O2T_SIZE.default
    t2o_size: int = cp.T2O_SIZE.default
    heartbeat_sizes: tuple[int, ...] = (0, 2, 6)
    """O→T connection sizes accepted for input-only and listen-only (vendors differ)."""
    rpi_min_us: int = cp.RPI_US.minimum
    rpi_max_us: int = cp.RPI_US.maximum
    max_connections: int = 8
    idle_behaviour: IdleBehaviour = IdleBehaviour.HOLD
    t2o_port_default: int = ENIP_UDP_PORT
    """Where T→O goes on the originator's address unless its 0x8001 item says otherwise."""
    identity: IdentityInfo = field(default_factory=default_identity)
    seed: int | None = None
    """Seed of the random numbers for connection IDs and fault drops; ``None`` (the default):
    drawn from the operating system at every start, so a restarted target's first O→T
    connection ID is not the one it gave before (the originator could take the new connection
    for the old one); a seed repeats them (tests)."""
    batch_period_s: float = 0.040
    """How often the target wakes while a connection runs at an RPI under 10 ms (the I/O cycle
    of the emulated controller): it reads the O→T that came meanwhile and the robot's data once
    per wake-up, so a command or an event is in T→O at most this much later (each wake-up costs
    far more CPU than a packet: docs/protocol.md "Timing"). At 10 ms and longer it wakes for each
    O→T packet, and for T→O once per packet, or, while T→O streams, when the robot's frame changes
    by itself. Watchdogs do not wait for it (the pump reports silence)."""
    max_tcp_sessions: int = 64
    """TCP connections on the encapsulation port held at once; one more is closed at once and
    counted (``tcp_sessions_refused``), so idle connections cannot exhaust the process's file
    descriptors (docs/operations.md "Emulator hardening")."""
    incomplete_message_timeout_s: float = 10.0
    """Longest wait for the rest of an encapsulation message once its first byte came, and for
    the first message of a connection (or the next, while it has no registered session): the
    connection is then dropped and counted (``tcp_sessions_timed_out``). A registered session
    may idle between messages up to ``session_inactivity_timeout_s``."""
    session_inactivity_timeout_s: float | None = 120.0
    """A registered session silent this long is closed and counted (``tcp_sessions_inactive``):
    the encapsulation inactivity timeout, whose default is the TCP/IP Interface object's
    attribute 13 (CIP Vol 2 Chapter 5). ``None``: never. Class 1 connections carry on (UDP)."""
    discovery: bool = True
    """Answer ListIdentity / ListServices / ListInterfaces on UDP (CIP Vol 2 §2-4.2), unicast
    and broadcast (``emulator.discovery``)."""
    discovery_port: int = ENIP_TCP_PORT
    """UDP port of the discovery server: 44818, as the TCP one (CIP Vol 2 §2-2)."""
    discovery_broadcast_hosts: tuple[str, ...] | None = None
    """Broadcast addresses whose datagrams the discovery server also receives (a socket bound to
    ``host`` gets unicast only). ``None``: 255.255.255.255, and 127.255.255.255 for a loopback
    ``host``; none for the wildcard host, whose socket gets them all."""
    control_token: str | None = None
    """When set, every control API request must carry ``Authorization: Bearer <token>``."""

    @property
    def o2t_connection_size(self) -> int:
        """O→T connection size: data + 2 (sequence count) + 4 (run/idle header)."""
        return self.o2t_size + 6

    @property
    def t2o_connection_size(self) -> int:
        """T→O connection size: data + 2 (sequence count); no run/idle header."""
        return self.t2o_size + 2
