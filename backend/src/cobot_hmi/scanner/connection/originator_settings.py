"""Layer: scanner. The settings of one class 1 connection (:class:`OriginatorSettings`) and
the helpers that derive what goes on the wire from them.
"""

from __future__ import annotations

import logging
import socket
from dataclasses import dataclass

from cobot_hmi import connection_params as cp
from cobot_hmi.codec import O2T_SIZE, T2O_SIZE
from cobot_hmi.enip.encapsulation import ENIP_UDP_PORT

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class OriginatorSettings:
    """The connection settings' defaults come from their one declaration
    (``cobot_hmi.connection_params``), shared with the service and the emulator."""

    robot_host: str
    tcp_port: int = cp.ENIP_TCP_PORT.default
    local_host: str | None = None
    """The local address of the UDP port and the TCP session. None: the address that routes
    to the target (so another process may hold UDP 2222 on another address); "0.0.0.0": all."""
    local_udp_port: int = cp.CLASS1_UDP_PORT.default
    rpi_us: int = cp.RPI_US.default
    timeout_multiplier: int = cp.TIMEOUT_MULTIPLIER.default
    """Connection timeout = RPI × (4 << multiplier): 2 → RPI × 16."""
    input_only: bool = False
    large_forward_open: bool = False
    config_instance: int = cp.CONFIG_INSTANCE.default
    o2t_instance: int = cp.O2T_INSTANCE.default
    t2o_instance: int = cp.T2O_INSTANCE.default
    heartbeat_instance: int = cp.HEARTBEAT_INSTANCE.default
    o2t_size: int = cp.O2T_SIZE.default
    t2o_size: int = cp.T2O_SIZE.default
    request_t2o_port: int | None = None
    """Ask for T→O on this local port (a Sockaddr Info 0x8001 item) instead of 2222."""
    heartbeat_o2t_size: int = 0
    """O→T connection size of an input-only connection (targets accept 0, 2 or 6)."""
    o2t_data: bytes | None = None
    """The O→T data to send, zero-filled to ``o2t_size``, in every packet until it is changed
    (never replaced by the bumpless takeover). None: what an explicit read of the O→T assembly
    returns (where the target allows it), else zeros, and at the robot layout's sizes the
    takeover of the robot's outputs from the first frame."""
    raw: bool = False
    """Hand every T→O packet's data to ``on_data`` even when its size is the robot layout's."""
    api_bounds_us: tuple[int, int] | None = None
    """The packet intervals (API) a Forward Open reply may grant, inclusive. None: RPI / 2 to
    RPI × 2. A reply outside is refused (and the connection closed): a target granting 1 µs
    would have us send a datagram per microsecond, one granting hours would leave a dead
    connection looking alive."""
    backoff_initial_s: float = 0.1
    backoff_max_s: float = 1.0
    """Longest wait between two attempts at an absent or lost robot: 0.1 s doubling to this.
    About a PLC's own retry period, so a robot back from a restart or a cable pull carries
    frames again within about a second of accepting connections; one TCP connect a second is
    nothing to an absent host (on a network, each attempt to a host that does not answer also
    waits ``tcp_timeout_s`` first)."""
    refused_backoff_max_s: float = 5.0
    """The same for a robot that answers and refuses (a Forward Open error: a wrong
    assembly, a connection another scanner owns): nothing changes for that within a second,
    and every attempt costs the robot a line in its log."""
    tcp_timeout_s: float = 5.0
    first_frame_timeout_s: float = 2.0
    """How long after a Forward Open the first T→O frame may take (at least the watchdog)."""
    t2o_batch_s: float = 0.040
    """At RPIs shorter than ``BATCH_PERIOD_S`` (10 ms), how often we wake for T→O at most: the
    frames of each batch are read together, each with the kernel's receive time. Neither O→T
    (a change goes into the next packet at once) nor the watchdog (the pump reports silence)
    waits for it."""

    @property
    def udp_port(self) -> int:
        return self.request_t2o_port if self.request_t2o_port is not None else self.local_udp_port

    @property
    def decodes_frames(self) -> bool:
        """T→O is the robot's frame: its layout's size, or longer (a controller configured to
        append general-purpose registers: the frame keeps them as ``extra``), and raw mode not
        asked for."""
        return not self.raw and self.t2o_size >= T2O_SIZE

    @property
    def o2t_is_command(self) -> bool:
        """O→T is the robot's command image (its layout's size, an exclusive owner)."""
        return not self.input_only and self.o2t_size == O2T_SIZE

    @property
    def api_range_us(self) -> tuple[int, int]:
        if self.api_bounds_us is not None:
            return self.api_bounds_us
        return self.rpi_us // 2, self.rpi_us * 2

    def initial_o2t_data(self) -> bytes:
        """``o2t_data`` zero-filled to the O→T size (a ``ValueError`` if it is longer)."""
        return fit_o2t_data(self.o2t_data or b"", self.o2t_size)


def fit_o2t_data(data: bytes, size: int) -> bytes:
    """``data`` zero-filled to ``size`` bytes; a ``ValueError`` when it is longer."""
    if len(data) > size:
        raise ValueError(f"{len(data)} bytes of O→T data exceed the O→T size of {size} bytes")
    return data.ljust(size, b"\x00")


def local_address_to(host_ip: str) -> str:
    """The local address the kernel's routing table picks to reach ``host_ip`` (a UDP
    ``connect`` sends nothing)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect((host_ip, ENIP_UDP_PORT))
        except OSError as error:
            raise OSError(f"no local address routes to {host_ip}: {error}") from None
        address: str = probe.getsockname()[0]
        return address
