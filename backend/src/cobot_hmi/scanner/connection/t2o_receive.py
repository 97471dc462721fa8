"""Layer: scanner. The T→O receive path of a class 1 connection: what the
:class:`~cobot_hmi.scanner.io_port.IoPort` hands over (a ``T2OConsumer``), the sequence and
size checks, the decode (once per new payload), the counters and interval window, the T→O pace,
the bumpless takeover from the first frame, and the watchdog on T→O silence.
"""

from __future__ import annotations

import asyncio
import logging
import time

from cobot_hmi.codec import CodecError, CommandImage, Frame, decode_frame, encode_command
from cobot_hmi.enip import io
from cobot_hmi.enip.sequence import DUPLICATE, STALE
from cobot_hmi.scanner.connection.core import Link, OriginatorCore

log = logging.getLogger(__name__)


class T2OReceiver(OriginatorCore):
    """T→O packets in, frames or data out to the callbacks; the watchdog."""

    # T2OConsumer: what the IoPort hands us.

    def t2o_batch_read(self) -> None:
        """After each wake-up for T→O (a batch, or the pump's word that T→O fell silent for the
        connection timeout): push the fallback timer back and look at the watchdog."""
        link = self._link
        if link is not None and link.o2t is not None:
            link.o2t.t2o_read()
            self._check_t2o_silence(link, asyncio.get_running_loop().time(), 0.0)

    def t2o_foreign(self) -> None:
        self.foreign += 1

    def t2o_malformed(self) -> None:
        self.malformed += 1

    def _check_t2o_silence(self, link: Link, now: float, lag_s: float) -> None:
        """The watchdog (docs/protocol.md, Forward Open: RPI × (4 << multiplier)). Checked after
        each T→O wake-up, including the one the pump gives once T→O has been silent for the
        timeout, and at the O→T stream's fallback timer: a steady T→O stream costs no wake-up of
        its own for it.

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
        timeout_s = self._timeout_s(link)
        if now - link.last_rx < timeout_s or lag_s > link.o2t_api_us / 1e6:
            return
        if self._port is not None:
            self._port.read_now()
            if now - link.last_rx < timeout_s:
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
                f"no T→O for {timeout_s * 1e3:.0f} ms (RPI {link.t2o_api_us / 1e3:g} ms × "
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
        self._check_t2o_silence(link, now, 0.0)

    def t2o_packet(self, packet: io.IoPacket, arrived: float) -> None:
        """One T→O packet of this connection from the target's address (``arrived``: the loop
        time the kernel received it)."""
        link = self._link
        if link is None:
            self.foreign += 1
            return
        payload = packet.payload
        s = self.settings
        if packet.cip_seq is None or len(payload) != s.t2o_size:
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
        if not s.decodes_frames:
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
            self._seed(frame)
        if self.on_frame is not None:
            try:
                self.on_frame(frame, payload, received_at, packet.encap_seq)
            except Exception:
                log.exception("on_frame callback failed")

    def _count_frame(self, link: Link, arrived: float) -> None:
        previous = link.last_frame_at
        link.last_frame_at = arrived
        if previous is not None:
            interval_s = arrived - previous
            self._window.add(interval_s * 1e3)
            if interval_s > link.t2o_api_us * 1.5e-6:
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

    def _seed(self, frame: Frame) -> None:
        """Bumpless takeover: the command image becomes what the robot does now, unless the
        O→T data was given (``o2t_data``: what is sent is what was asked for)."""
        self._seeded = True
        if self.settings.o2t_is_command and self.settings.o2t_data is None:
            bits = self._explicit_bits or self.command.bit_input_registers
            self.command = CommandImage(
                controlbox_do=frame.controlbox_do,
                tool_do=frame.tool_do,
                analog_output_type=frame.analog_output_type,
                analog_output=frame.analog_output,
                bit_input_registers=bits,
            )
            self._o2t_bytes = encode_command(self.command)
            self._rebuild_o2t()
        self._first_data()
