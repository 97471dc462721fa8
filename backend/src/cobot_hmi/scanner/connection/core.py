"""Layer: scanner. The state one class 1 connection's parts share: the negotiated
parameters of a Forward Open (:class:`Link`) and :class:`OriginatorCore`, which holds the
callbacks, the command image, the counters and the connection's futures that the send path,
the receive path and the lifecycle (``o2t_send``, ``t2o_receive``, ``lifecycle``) work on.
"""

from __future__ import annotations

import asyncio
import random
from collections.abc import Callable
from dataclasses import dataclass, field

from cobot_hmi.codec import CommandImage, Frame, decode_command, encode_command, zero_command
from cobot_hmi.enip.connection_manager import connection_timeout_us
from cobot_hmi.enip.encapsulation import ENIP_UDP_PORT
from cobot_hmi.enip.sequence import SequenceTracker
from cobot_hmi.scanner.connection.settings import OriginatorSettings
from cobot_hmi.scanner.connection.state import ConnectionState
from cobot_hmi.scanner.io_port import IoPort, hurry_window_s
from cobot_hmi.scanner.o2t_stream import O2TStream
from cobot_hmi.scanner.session import EnipSession
from cobot_hmi.scanner.stats import IntervalWindow
from cobot_hmi.scanner.t2o_pace import PaceWatch, SlowTarget
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
    more: ``T2OReceiver._check_t2o_silence``); ``None`` while T→O comes."""


class OriginatorCore:
    """What a class 1 connection holds; the parts of :class:`~cobot_hmi.scanner.originator.
    Originator` build on it."""

    def __init__(
        self,
        settings: OriginatorSettings,
        *,
        on_frame: Callable[[Frame, bytes, float, int], None] | None = None,
        on_state: Callable[[ConnectionState, str | None], None] | None = None,
        on_data: Callable[[bytes, float, int], None] | None = None,
        on_slow_target: Callable[[SlowTarget | None], None] | None = None,
        io_port: IoPort | None = None,
    ) -> None:
        """``on_frame(frame, payload, received_at, t2o_sequence)``: each new T→O frame when T→O
        is the robot's layout, with the payload it was decoded from (consumers that keep bytes
        slice those instead of encoding the frame again); ``on_data(payload, received_at,
        t2o_sequence)``: each new T→O packet's data otherwise (``settings.decodes_frames``).
        ``received_at``: epoch seconds the kernel received it; ``t2o_sequence``: the
        encapsulation sequence number its packet carried in the Sequenced Address item (CIP
        Vol 2 §2-6, §3-4.2; UDINT, the target raises it per packet), so a consumer can tell the
        frames it keeps apart by the wire's own numbering (``frames`` counts them).
        ``on_slow_target(slow)``: the target was found sending T→O slower than its grant (a
        ``SlowTarget``), or keeping it again (None), once each time (``scanner.t2o_pace``).
        ``io_port``: the UDP port to share (None: one of our own, opened on start and closed on
        stop). A ``ValueError`` when ``o2t_data`` does not fit the O→T size."""
        self.settings = settings
        self.on_frame = on_frame
        self.on_state = on_state
        self.on_data = on_data
        self.on_slow_target = on_slow_target
        self.state = ConnectionState.IDLE
        self.reason: str | None = None
        self.latest: tuple[Frame, float] | None = None
        """The last frame and its epoch receive time (T→O of the robot's layout)."""
        self.latest_data: tuple[bytes, float] | None = None
        """The last T→O data and its epoch receive time (T→O of any other size, or raw)."""
        self.run = False
        self.command: CommandImage = zero_command()
        self._o2t_bytes = settings.initial_o2t_data()
        if settings.o2t_is_command:
            if settings.o2t_data is not None:
                self.command = decode_command(self._o2t_bytes)
            self._o2t_bytes = encode_command(self.command)
        self._rng = random.Random()
        self._port = io_port
        self._owns_port = io_port is None
        self._session: EnipSession | None = None
        self._link: Link | None = None
        self._supervisor: asyncio.Task[None] | None = None
        self._lost: asyncio.Future[str] | None = None
        self._first_frame: asyncio.Future[None] | None = None
        self._connected_event = asyncio.Event()
        self._explicit_bits: tuple[bool, ...] | None = None
        self._seeded = False
        self._stopping = False
        self._window = IntervalWindow()
        self._pace = PaceWatch()
        self._connected_since: float | None = None
        self.packets_in = 0
        self._packets_out_closed = 0
        """O→T packets sent by the streams of connections closed since."""
        self.gaps = 0
        self.duplicates = 0
        self.late = 0
        self.malformed = 0
        self.stale = 0
        self.foreign = 0
        self.frames = 0

    @property
    def _t2o_batch_s(self) -> float:
        s = self.settings
        return s.t2o_batch_s if s.rpi_us < BATCH_PERIOD_S * 1e6 else 0.0

    def _timeout_s(self, link: Link) -> float:
        return connection_timeout_us(link.t2o_api_us, self.settings.timeout_multiplier) / 1e6

    def _rebuild_o2t(self) -> None:
        link = self._link
        if link is not None and link.o2t is not None:
            link.o2t.rebuild()
            if self._port is not None:
                # The change's confirmation is the robot's next frames: read them as they come.
                self._port.hurry(hurry_window_s(link.t2o_api_us / 1e6))
