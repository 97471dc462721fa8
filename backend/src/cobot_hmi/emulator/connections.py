"""Layer: emulator (no I/O here). Imports ``cobot_hmi.enip`` and the emulator's settings.

The target's connection table and its admission rules for a Forward Open (issue 3, "The
target"): which connection point pair makes an exclusive owner, an input-only or a listen-only
connection, and the extended status (and expected size) of every refusal.
"""

from __future__ import annotations

import asyncio
from collections import deque
from dataclasses import dataclass, field
from enum import StrEnum

from cobot_hmi.emulator.settings import TargetSettings
from cobot_hmi.enip import epath
from cobot_hmi.enip.connection_manager import (
    TRANSPORT_CLASS1_CYCLIC,
    ConnectionType,
    ForwardOpenRequest,
    connection_timeout_us,
)
from cobot_hmi.enip.errors import PathError
from cobot_hmi.enip.status import ExtendedStatus


class ConnectionKind(StrEnum):
    OWNER = "owner"
    INPUT_ONLY = "input-only"
    LISTEN_ONLY = "listen-only"


class RefusalError(Exception):
    """A Forward Open the target refuses: general status 0x01 with ``extended``."""

    def __init__(self, extended: int, *additional: int) -> None:
        super().__init__(f"extended status 0x{extended:04X}")
        self.extended = extended
        self.additional = additional

    @property
    def words(self) -> tuple[int, ...]:
        return (self.extended, *self.additional)


@dataclass(eq=False)
class IoConnection:
    """One class 1 connection: its negotiated parameters and its live counters."""

    kind: ConnectionKind
    o2t_id: int
    t2o_id: int
    triplet: tuple[int, int, int]
    peer: tuple[str, int]
    """Where T→O goes: the originator's address and its requested (or the default) port."""
    o2t_rpi_us: int
    t2o_rpi_us: int
    timeout_multiplier: int
    o2t_connection_size: int
    t2o_connection_size: int
    request_path: bytes
    opened_at: float
    """Epoch seconds."""
    run: bool = False
    last_rx: float = 0.0
    """Loop time of the last O→T packet (or of the open, before the first one)."""
    last_o2t_encap_seq: int | None = None
    last_o2t_cip_seq: int | None = None
    last_applied: bytes | None = None
    t2o_encap_seq: int = 0
    t2o_cip_seq: int = 0
    packets_in: int = 0
    packets_out: int = 0
    duplicates: int = 0
    o2t_gaps: int = 0
    """O→T packets missing (CIP sequence count jumps), summed."""
    last_o2t_at: float | None = None
    o2t_intervals_ms: deque[float] = field(default_factory=lambda: deque(maxlen=16_384))
    """Recent O→T arrival intervals (new data only), for the status API and the bench."""
    t2o_last_due: float = 0.0
    """Loop time the last T→O packet handed to the cyclic pump is due (a drift-free schedule:
    + RPI each packet)."""
    t2o_last_kind: str = "none"
    """What became of that packet: "sent" (queued as built), "corrupt" (queued cut short by the
    corrupt fault), "dropped" (the drop fault kept it back) or "none"."""
    t2o_streaming: bool = False
    """T→O goes out as a periodic stream of the cyclic pump (the robot's data unchanged between
    our wake-ups and no per-packet fault active), not packet by packet from the queue."""
    t2o_stream_data: bytes | None = None
    """The frame bytes the stream sends."""
    t2o_stream_first_seq: int = 0
    """The encapsulation sequence number of the stream's first packet."""
    t2o_stream_counted: int = 0
    """Packets of the stream already added to ``packets_out``."""
    watchdog: asyncio.TimerHandle | None = None

    def cancel_timers(self) -> None:
        if self.watchdog is not None:
            self.watchdog.cancel()
        self.watchdog = None

    @property
    def timeout_s(self) -> float:
        """Watchdog: O→T RPI × (4 << multiplier) (ethernetip.md "Forward Open")."""
        return connection_timeout_us(self.o2t_rpi_us, self.timeout_multiplier) / 1e6

    @property
    def produces(self) -> bool:
        """Whether T→O production depends on this connection alone (not listen-only)."""
        return self.kind is not ConnectionKind.LISTEN_ONLY


def _check_key(key: epath.ElectronicKey | None, settings: TargetSettings) -> None:
    if key is None:
        return
    identity = settings.identity
    if (key.vendor_id and key.vendor_id != identity.vendor_id) or (
        key.product_code and key.product_code != identity.product_code
    ):
        raise RefusalError(ExtendedStatus.VENDOR_PRODUCT_MISMATCH)
    if key.device_type and key.device_type != identity.device_type:
        raise RefusalError(ExtendedStatus.DEVICE_TYPE_MISMATCH)
    major = key.major_revision & 0x7F
    if major and (
        major != identity.revision_major
        or (
            key.minor_revision
            and key.minor_revision != identity.revision_minor
            and not key.major_revision & 0x80
        )
    ):
        raise RefusalError(ExtendedStatus.REVISION_MISMATCH)


def admit(
    request: ForwardOpenRequest,
    settings: TargetSettings,
    table: list[IoConnection],
) -> ConnectionKind:
    """The kind of connection ``request`` opens, or :class:`RefusalError` with its status."""
    if request.transport != TRANSPORT_CLASS1_CYCLIC:
        raise RefusalError(ExtendedStatus.TRANSPORT_NOT_SUPPORTED)
    if any(conn.triplet == request.triplet for conn in table):
        raise RefusalError(ExtendedStatus.CONNECTION_IN_USE)
    try:
        path = epath.decode_connection_path(request.path)
    except PathError:
        raise RefusalError(ExtendedStatus.INVALID_SEGMENT_IN_PATH) from None
    if path.class_id != epath.CLASS_ASSEMBLY or len(path.points) != 2:
        raise RefusalError(ExtendedStatus.INVALID_SEGMENT_IN_PATH)
    _check_key(path.key, settings)
    o2t_point, t2o_point = path.points
    if path.config_instance != settings.config_instance or t2o_point != settings.t2o_instance:
        raise RefusalError(ExtendedStatus.INVALID_APPLICATION_PATH)
    kinds = {
        settings.o2t_instance: ConnectionKind.OWNER,
        settings.input_only_instance: ConnectionKind.INPUT_ONLY,
        settings.listen_only_instance: ConnectionKind.LISTEN_ONLY,
    }
    kind = kinds.get(o2t_point)
    if kind is None:
        raise RefusalError(ExtendedStatus.INVALID_APPLICATION_PATH)
    if path.config_data:
        raise RefusalError(ExtendedStatus.INVALID_CONFIGURATION_SIZE, 0)
    for rpi_us in (request.o2t_rpi_us, request.t2o_rpi_us):
        if not settings.rpi_min_us <= rpi_us <= settings.rpi_max_us:
            raise RefusalError(ExtendedStatus.RPI_NOT_SUPPORTED)
    if request.timeout_multiplier > 7:
        raise RefusalError(ExtendedStatus.TIMEOUT_MULTIPLIER_NOT_ACCEPTABLE)
    if request.o2t_params.connection_type is not ConnectionType.POINT_TO_POINT:
        raise RefusalError(ExtendedStatus.INVALID_O2T_CONNECTION_TYPE)
    if request.t2o_params.connection_type is not ConnectionType.POINT_TO_POINT:
        # Multicast T→O is not produced by this target: every connection is point-to-point.
        raise RefusalError(ExtendedStatus.INVALID_T2O_CONNECTION_TYPE)
    o2t_size = request.o2t_params.size_bytes
    if kind is ConnectionKind.OWNER:
        if o2t_size != settings.o2t_connection_size:
            raise RefusalError(ExtendedStatus.INVALID_O2T_SIZE, settings.o2t_connection_size)
    elif o2t_size not in settings.heartbeat_sizes:
        raise RefusalError(ExtendedStatus.INVALID_O2T_SIZE, settings.heartbeat_sizes[0])
    if request.t2o_params.size_bytes != settings.t2o_connection_size:
        raise RefusalError(ExtendedStatus.INVALID_T2O_SIZE, settings.t2o_connection_size)
    if kind is ConnectionKind.OWNER and any(c.kind is ConnectionKind.OWNER for c in table):
        raise RefusalError(ExtendedStatus.OWNERSHIP_CONFLICT)
    if kind is ConnectionKind.LISTEN_ONLY and not any(c.produces for c in table):
        raise RefusalError(ExtendedStatus.NON_LISTEN_ONLY_NOT_OPENED)
    if len(table) >= settings.max_connections:
        raise RefusalError(ExtendedStatus.OUT_OF_CONNECTIONS)
    return kind
