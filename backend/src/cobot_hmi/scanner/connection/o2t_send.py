"""Layer: scanner. The O→T sender of a class 1 connection (:class:`O2TSender`): the data and the
run/idle state the cyclic pump's stream carries (rebuilt on a change), the packet it is built
from, the bumpless takeover of the robot's outputs, and the count of packets that left.
"""

from __future__ import annotations

import asyncio

from cobot_hmi.codec import (
    CodecError,
    CommandImage,
    Frame,
    decode_command,
    encode_command,
    zero_command,
)
from cobot_hmi.enip import io
from cobot_hmi.scanner.connection.link import Link
from cobot_hmi.scanner.connection.originator_settings import OriginatorSettings, fit_o2t_data
from cobot_hmi.scanner.connection.state import (
    ConnectionState,
    ConnectionStatus,
    NotConnectedError,
    ReadOnlyError,
)
from cobot_hmi.scanner.io_port import IoPort, hurry_window_s


class O2TSender:
    """What O→T carries, its changes, and the packet the connection's stream builds from it.
    Given the connection's ``status`` (no run without a connection); the lifecycle attaches each
    open connection (:meth:`attach`) and detaches it at its teardown."""

    def __init__(self, settings: OriginatorSettings, status: ConnectionStatus) -> None:
        """A ``ValueError`` when ``settings.o2t_data`` does not fit the O→T size."""
        self.settings = settings
        self._status = status
        self.run = False
        self.command: CommandImage = zero_command()
        self._o2t_bytes = settings.initial_o2t_data()
        if settings.o2t_is_command:
            if settings.o2t_data is not None:
                self.command = decode_command(self._o2t_bytes)
            self._o2t_bytes = encode_command(self.command)
        self._explicit_bits: tuple[bool, ...] | None = None
        """The bit input registers an explicit read of the O→T assembly found (the takeover
        keeps them)."""
        self._link: Link | None = None
        self._port: IoPort | None = None
        self._packets_out_closed = 0
        """O→T packets sent by the streams of connections closed since."""

    # ------------------------------------------------------------------ the connection's

    def attach(self, link: Link, port: IoPort) -> None:
        """A Forward Open leaves for ``link`` on ``port``: idle until someone runs; the stream
        the lifecycle starts on ``link.o2t`` builds from :meth:`packet`."""
        self.run = False
        self._link, self._port = link, port

    def detach(self) -> None:
        """The connection is torn down: its stream stops, and the packets it sent stay
        counted."""
        link, self._link = self._link, None
        if link is not None and link.o2t is not None:
            self._packets_out_closed += link.o2t.stop()

    def adopt_assembly(self, data: bytes | None) -> None:
        """What an explicit read of the O→T assembly returned before the Forward Open (None:
        no read, or a failed one): the first O→T packet carries it, and the command image's
        bit input registers keep it (bumpless takeover). Data that is not a command image of
        the robot's layout changes nothing."""
        self._explicit_bits = None
        if data is None:
            return
        if self.settings.o2t_is_command:
            try:
                image = decode_command(data)
            except CodecError:
                return
            self.command = image
            self._explicit_bits = image.bit_input_registers
        self._o2t_bytes = bytes(data)

    def seed(self, frame: Frame) -> None:
        """Bumpless takeover at the first frame: the command image becomes what the robot does
        now, unless the O→T data was given (``o2t_data``: what is sent is what was asked
        for)."""
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
            self._rebuild()

    def packet(self, link: Link) -> bytes:
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

    # ------------------------------------------------------------------ the users'

    @property
    def packets_out(self) -> int:
        """O→T packets that left (counted by the cyclic pump as it sends them)."""
        link = self._link
        current = link.o2t.sent if link is not None and link.o2t is not None else 0
        return self._packets_out_closed + current

    @property
    def o2t_data(self) -> bytes:
        """The O→T data the next packet carries (after the run/idle header)."""
        return self._o2t_bytes

    def set_run(self, run: bool) -> None:
        if self.settings.input_only:
            raise ReadOnlyError("input-only connection: the outputs belong to another owner")
        status = self._status
        if status.state is not ConnectionState.CONNECTED:
            raise NotConnectedError(
                f"not connected ({status.state}: {status.reason or 'no reason'})"
            )
        if run != self.run:
            self.run = run
            self._rebuild()

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
        self._rebuild()
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
        self._rebuild()
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

    def _rebuild(self) -> None:
        link = self._link
        if link is not None and link.o2t is not None:
            link.o2t.rebuild()
            if self._port is not None:
                # The change's confirmation is the robot's next frames: read them as they come.
                self._port.hurry(hurry_window_s(link.t2o_api_us / 1e6))
