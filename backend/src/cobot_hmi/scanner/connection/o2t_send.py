"""Layer: scanner. The O→T send path of a class 1 connection: the data and the run/idle
state the cyclic pump's stream carries (rebuilt on a change), the packet it is built from, and
the count of packets that left.
"""

from __future__ import annotations

import asyncio

from cobot_hmi.codec import CommandImage, decode_command, encode_command
from cobot_hmi.enip import io
from cobot_hmi.scanner.connection.core import Link, OriginatorCore
from cobot_hmi.scanner.connection.settings import fit_o2t_data
from cobot_hmi.scanner.connection.state import ConnectionState, NotConnectedError, ReadOnlyError


class O2TSender(OriginatorCore):
    """Changes to what O→T carries, and the packet the stream builds from it."""

    @property
    def packets_out(self) -> int:
        """O→T packets that left (counted by the cyclic pump as it sends them)."""
        link = self._link
        current = link.o2t.sent if link is not None and link.o2t is not None else 0
        return self._packets_out_closed + current

    def set_run(self, run: bool) -> None:
        if self.settings.input_only:
            raise ReadOnlyError("input-only connection: the outputs belong to another owner")
        if self.state is not ConnectionState.CONNECTED:
            raise NotConnectedError(f"not connected ({self.state}: {self.reason or 'no reason'})")
        if run != self.run:
            self.run = run
            self._rebuild_o2t()

    @property
    def o2t_data(self) -> bytes:
        """The O→T data the next packet carries (after the run/idle header)."""
        return self._o2t_bytes

    def set_o2t_data(self, data: bytes) -> int:
        """Put ``data`` (zero-filled to the O→T size) on the wire as it is; returns the
        ``packets_out`` count after which it has gone out. A ``ValueError`` when it is longer
        than the O→T size or the connection has no O→T data (input-only)."""
        s = self.settings
        if s.input_only:
            raise ReadOnlyError("input-only connection: it sends no O→T data")
        fitted = fit_o2t_data(data, s.o2t_size)
        if s.o2t_is_command:
            self.command = decode_command(fitted)
        self._o2t_bytes = fitted
        self._rebuild_o2t()
        return self.packets_out + 1

    def set_command(self, image: CommandImage) -> int:
        """Put ``image`` on the wire; returns the ``packets_out`` count after which it has
        gone out (see :meth:`wait_sent`). A ``ValueError`` when O→T is not the robot's command
        image (another size: :meth:`set_o2t_data`)."""
        if not self.settings.o2t_is_command:
            raise ValueError(
                f"O→T of {self.settings.o2t_size} bytes is not the robot's command image"
            )
        self.command = image
        self._o2t_bytes = encode_command(image)
        # The pump's stream carries the new image from its next packet on.
        self._rebuild_o2t()
        return self.packets_out + 1

    async def wait_sent(self, packets_out: int, timeout_s: float) -> bool:
        """Whether ``packets_out`` O→T packets have left within ``timeout_s``. The pump sends
        without waking us, so this looks again every half RPI (only while someone waits)."""
        loop = asyncio.get_running_loop()
        end = loop.time() + timeout_s
        link = self._link
        step_s = max(0.001, (link.o2t_api_us if link is not None else 10_000) / 2e6)
        while self.packets_out < packets_out:
            if loop.time() >= end:
                return False
            await asyncio.sleep(min(step_s, max(0.0, end - loop.time())))
        return True

    def _o2t_packet(self, link: Link) -> bytes:
        """The O→T datagram, its sequence numbers left for the pump to write: the O→T data
        with the run/idle header, or an input-only connection's heartbeat."""
        s = self.settings
        if not s.input_only:
            return io.encode_io(link.o2t_id, 0, 0, self._o2t_bytes, io.RUN_BIT if self.run else 0)
        if s.heartbeat_o2t_size == 0:
            return io.encode_heartbeat(link.o2t_id, 0)
        if s.heartbeat_o2t_size == 6:
            return io.encode_io(link.o2t_id, 0, 0, b"", 0)
        return io.encode_io(link.o2t_id, 0, 0, b"")
