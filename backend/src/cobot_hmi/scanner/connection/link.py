"""Layer: scanner. One Forward Open's worth of a class 1 connection (:class:`Link`): the
negotiated parameters and the sequence state the originator's parts hand one another (the
lifecycle makes it, the O→T sender and the T→O receiver work on it while it is open), and the
figures derived from it and the settings.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cobot_hmi.codec import Frame
from cobot_hmi.enip.connection_manager import connection_timeout_us
from cobot_hmi.enip.encapsulation import ENIP_UDP_PORT
from cobot_hmi.enip.sequence import SequenceTracker
from cobot_hmi.scanner.connection.originator_settings import OriginatorSettings
from cobot_hmi.scanner.o2t_stream import O2TStream
from cobot_hmi.udp_endpoint import BATCH_PERIOD_S


@dataclass
class Link:
    """One Forward Open's worth of negotiated parameters and sequence state."""

    t2o_id: int
    connection_serial: int
    originator_serial: int
    path: bytes
    target_host: str
    """The target's address: T→O from anywhere else is foreign."""
    o2t_api_us: int
    t2o_api_us: int
    """Until the reply is read: the RPI asked for."""
    o2t_id: int = 0
    o2t_addr: tuple[str, int] = ("0.0.0.0", ENIP_UDP_PORT)
    sequence: SequenceTracker = field(default_factory=SequenceTracker)
    last_frame_at: float | None = None
    """Loop time of the last new frame."""
    last_rx: float = 0.0
    """Loop time the kernel received the last accepted T→O packet."""
    last_payload: tuple[bytes, Frame] | None = None
    """The last T→O payload decoded, and its frame."""
    o2t: O2TStream | None = None
    routed: bool = False
    silence_seen_at: float | None = None
    """Loop time the watchdog first saw T→O silent past the timeout (its verdict waits one RPI
    more: ``T2OReceiver.check_silence``); ``None`` while T→O comes."""


def timeout_s(link: Link, settings: OriginatorSettings) -> float:
    """The connection's timeout (docs/protocol.md, Forward Open: RPI × (4 << multiplier)), at
    the T→O API the target granted."""
    return connection_timeout_us(link.t2o_api_us, settings.timeout_multiplier) / 1e6


def t2o_batch_s(settings: OriginatorSettings) -> float:
    """How often T→O wakes us at most: ``settings.t2o_batch_s`` at RPIs shorter than
    ``BATCH_PERIOD_S``, else at each packet."""
    return settings.t2o_batch_s if settings.rpi_us < BATCH_PERIOD_S * 1e6 else 0.0
