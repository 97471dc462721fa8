"""Layer: scanner. The T→O receiver of a class 1 connection (:class:`T2OReceiver`): what the
:class:`~cobot_hmi.scanner.io_port.IoPort` hands over (it is the port's ``T2OConsumer``), the
sequence and size checks, the decode (once per new payload), the counters and interval window,
the T→O pace, the first frame (the bumpless takeover is the O→T sender's ``seed``), and the
watchdog on T→O silence.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable

from cobot_hmi.codec import CodecError, Frame, decode_frame
from cobot_hmi.enip import io
from cobot_hmi.enip.sequence import DUPLICATE, STALE
from cobot_hmi.scanner.connection.link import Link, timeout_s
from cobot_hmi.scanner.connection.originator_settings import OriginatorSettings
from cobot_hmi.scanner.io_port import IoPort
from cobot_hmi.scanner.stats import IntervalFigures, IntervalWindow
from cobot_hmi.scanner.t2o_pace import PaceWatch, SlowTarget

log = logging.getLogger(__name__)

FrameCallback = Callable[[Frame, bytes, float, int], None]
DataCallback = Callable[[bytes, float, int], None]
SlowTargetCallback = Callable[[SlowTarget | None], None]


class T2OReceiver:
    """T→O packets in, frames or data out to the callbacks; the figures they make; the
    watchdog. The lifecycle attaches each open connection (:meth:`attach`: its link, port and
    futures) and detaches it at its teardown."""

    def __init__(
        self,
        settings: OriginatorSettings,
        *,
        seed: Callable[[Frame], None],
        on_frame: FrameCallback | None = None,
        on_data: DataCallback | None = None,
        on_slow_target: SlowTargetCallback | None = None,
    ) -> None:
        """``seed(frame)``: the first frame of each connection (the O→T sender's takeover of
        the robot's outputs). The callbacks: :class:`~cobot_hmi.scanner.originator.
        Originator`'s."""
        self.settings = settings
        self.on_frame = on_frame
        self.on_data = on_data
        self.on_slow_target = on_slow_target
        self._seed = seed
        self.latest: tuple[Frame, float] | None = None
        """The last frame and its epoch receive time (T→O of the robot's layout)."""
        self.latest_data: tuple[bytes, float] | None = None
        """The last T→O data and its epoch receive time (T→O of any other size, or raw)."""
        self._link: Link | None = None
        self._port: IoPort | None = None
        self._lost: asyncio.Future[str] | None = None
        self._first_frame: asyncio.Future[None] | None = None
        self._seeded = False
        self._window = IntervalWindow()
        self._pace = PaceWatch()
        self._t2o_size = settings.t2o_size
        self._decodes_frames = settings.decodes_frames
        """Read once (the settings are frozen): ``t2o_packet`` runs per frame."""
        self._late_s = 0.0
        """An interval longer than this is late (1.5 RPI at the granted API)."""
        self._timeout = (0, 0.0)
        """The T→O API (µs) and the connection timeout (s) computed at it (``check_silence``
        runs after every wake-up)."""
        self.packets_in = 0
        self.gaps = 0
        self.duplicates = 0
        self.late = 0
        self.malformed = 0
        self.stale = 0
        self.foreign = 0
        self.frames = 0

    # ------------------------------------------------------------------ the connection's

    @property
    def link(self) -> Link | None:
        """The open connection's link (None between connections)."""
        return self._link

    def attach(
        self,
        link: Link,
        port: IoPort,
        *,
        lost: asyncio.Future[str],
        first_frame: asyncio.Future[None],
    ) -> None:
        """A Forward Open leaves for ``link``, whose T→O comes on ``port``: the watchdog's
        verdict goes to ``lost``, the first frame (or data) resolves ``first_frame``."""
        self._seeded = False
        self._window.clear()
        self._pace.restart(self.settings.rpi_us)  # again with the API the reply grants
        self._lost, self._first_frame = lost, first_frame
        self._link, self._port = link, port
        self._late_s = link.t2o_api_us * 1.5e-6

    def granted(self, t2o_api_us: int) -> None:
        """The Forward Open's reply grants T→O every ``t2o_api_us``: the pace is judged by
        it."""
        self._pace.restart(t2o_api_us)
        self._late_s = t2o_api_us * 1.5e-6

    def detach(self) -> None:
        """The connection is torn down: its futures are cancelled unless they are done."""
        self._link = None
        for future in (self._lost, self._first_frame):
            if future is not None and not future.done():
                future.cancel()

    def interval_figures(self) -> IntervalFigures:
        return self._window.figures()

    @property
    def slow_target(self) -> SlowTarget | None:
        """The target sends T→O less often than it granted, while it does."""
        return self._pace.slow

    # ------------------------------------------------------------------ T2OConsumer

    def t2o_batch_read(self, now: float) -> None:
        """After each wake-up for T→O (a batch, or the pump's word that T→O fell silent for the
        connection timeout) at loop time ``now``: push the fallback timer back and look at the
        watchdog."""
        self._window.bound()
        link = self._link
        if link is not None and link.o2t is not None:
            link.o2t.t2o_read(now)
            self.check_silence(link, now, 0.0)

    def t2o_foreign(self) -> None:
        self.foreign += 1

    def t2o_malformed(self) -> None:
        self.malformed += 1

    def t2o_packet(self, packet: io.IoPacket, arrived: float) -> None:
        """One T→O packet of this connection from the target's address (``arrived``: the loop
        time the kernel received it)."""
        link = self._link
        if link is None:
            self.foreign += 1
            return
        payload = packet.payload
        if packet.cip_seq is None or len(payload) != self._t2o_size:
            self.malformed += 1
            return
        verdict = link.sequence.accept(packet.encap_seq, packet.cip_seq)
        if verdict is STALE:
            self.stale += 1
            return
        link.last_rx = arrived
        self.packets_in += 1
        if self._pace.packet(arrived, packet.encap_seq):
            self._report_pace()
        if verdict is DUPLICATE:
            self.duplicates += 1
            return
        self.gaps += link.sequence.missed
        # Epoch seconds the kernel received it (read in batches, so not "now").
        received_at = arrived + (time.time() - time.monotonic())
        if not self._decodes_frames:
            self._count_frame(link, arrived)
            self.latest_data = (payload, received_at)
            self._first_data()
            if self.on_data is not None:
                try:
                    self.on_data(payload, received_at, packet.encap_seq)
                except Exception:
                    log.exception("on_data callback failed")
            return
        decoded = link.last_payload
        if decoded is not None and payload == decoded[0]:
            # The same bytes as the last frame (a robot refreshes its monitoring values about
            # every 100 ms, whatever the RPI): the same immutable Frame, decoded once.
            frame = decoded[1]
        else:
            try:
                frame = decode_frame(payload)
            except CodecError:
                self.malformed += 1
                return
            link.last_payload = (payload, frame)
        self._count_frame(link, arrived)
        self.latest = (frame, received_at)
        if not self._seeded:
            self._seeded = True
            self._seed(frame)
            self._first_data()
        if self.on_frame is not None:
            try:
                self.on_frame(frame, payload, received_at, packet.encap_seq)
            except Exception:
                log.exception("on_frame callback failed")

    # ------------------------------------------------------------------ the watchdog

    def check_silence(self, link: Link, now: float, lag_s: float) -> None:
        """The watchdog (docs/protocol.md, Forward Open: RPI × (4 << multiplier)). Checked after
        each T→O wake-up, including the one the pump gives once T→O has been silent for the
        timeout, and at the O→T stream's fallback timer (``on_timer``): a steady T→O stream
        costs no wake-up of its own for it.

        A timer firing more than an RPI late means this loop itself stalled (a busy machine):
        T→O packets may be waiting in the socket, unread. The verdict waits for a timer on time,
        which comes after the loop has read its sockets again.

        A silence past the timeout is judged on what has ARRIVED: the port hands over what the
        pump holds first. And the verdict waits until the silence has gone on for one RPI more
        while we watch (a look on time one RPI after the first): when the whole machine stops
        for longer than the timeout (a VM's host taking its CPUs: bench/soak saw both emulators'
        real-time pumps 33 ms late at once, the timeout at RPI 2 ms being 32 ms), the target
        stopped with us and sends its next packet as soon as it runs again, which may be just
        after our first look. A target really gone is declared one RPI later than the timeout."""
        api_us, limit_s = self._timeout
        if api_us != link.t2o_api_us:  # computed again only when the granted API changes
            limit_s = timeout_s(link, self.settings)
            self._timeout = (link.t2o_api_us, limit_s)
        if now - link.last_rx < limit_s or lag_s > link.o2t_api_us / 1e6:
            return
        if self._port is not None:
            self._port.read_now()
            if now - link.last_rx < limit_s:
                return
        rpi_s = link.t2o_api_us / 1e6
        seen = link.silence_seen_at
        if seen is None or seen < link.last_rx:  # a new silence: look again one RPI later
            link.silence_seen_at = now
            loop = asyncio.get_running_loop()
            loop.call_at(now + rpi_s, self._look_again, link, now + rpi_s)
            return
        if now - seen < rpi_s:
            return
        if self._lost is not None and not self._lost.done():
            self._lost.set_result(
                f"no T→O for {limit_s * 1e3:.0f} ms (RPI {link.t2o_api_us / 1e3:g} ms × "
                f"{4 << self.settings.timeout_multiplier}): connection timed out"
            )

    def _look_again(self, link: Link, due: float) -> None:
        """The watchdog's second look at a silence (its connection may be gone meanwhile)."""
        if self._link is not link:
            return
        loop = asyncio.get_running_loop()
        now = loop.time()
        if now - due > link.o2t_api_us / 1e6:  # our loop stalled again: after it reads T→O
            again = now + link.t2o_api_us / 1e6
            loop.call_at(again, self._look_again, link, again)
            return
        self.check_silence(link, now, 0.0)

    # ------------------------------------------------------------------ figures

    def _count_frame(self, link: Link, arrived: float) -> None:
        previous = link.last_frame_at
        link.last_frame_at = arrived
        if previous is not None:
            interval_s = arrived - previous
            self._window.add(interval_s * 1e3)
            if interval_s > self._late_s:
                self.late += 1
        self.frames += 1

    def _report_pace(self) -> None:
        slow, found = self._pace.slow, self._pace.found
        if slow is not None:
            log.info("T→O of %s: %s", self.settings.robot_host, slow.words())
        elif found is not None:
            log.info("T→O of %s: %s", self.settings.robot_host, found.kept_words())
        if self.on_slow_target is not None:
            try:
                self.on_slow_target(slow)
            except Exception:
                log.exception("on_slow_target callback failed")

    def _first_data(self) -> None:
        if self._first_frame is not None and not self._first_frame.done():
            self._first_frame.set_result(None)
