"""Layer: scanner (asyncio I/O, the originator role). Imports the codec, ``cobot_hmi.enip``,
``cobot_hmi.connection_params``, the scanner's own modules and the runtime support
(``udp_endpoint``); never the emulator or the service.

The backend's class 1 connection to the robot, held as a PLC holds it (issue 3, "The
originator"): RegisterSession, Forward Open (exclusive owner, or input-only as a read-only
mode), T→O received on UDP 2222 of the local address, O→T sent from the same socket at the RPI
on a drift-free schedule with the run/idle header (``o2t_stream``: built ahead, sent by the cyclic
pump), a watchdog on T→O silence, reconnection with backoff, and Forward Close +
UnRegisterSession on shutdown.

Any adapter (issue 11, "Scanning any adapter"): the instances and sizes are data; the robot's
layout is only their default. T→O is decoded to the robot's ``Frame`` only when it has the
layout's size or more (and raw mode is not asked for); otherwise each packet's data goes to
``on_data`` as bytes. O→T carries the command image when its size is the layout's, else bytes
(:meth:`Originator.set_o2t_data`), zero-filled to the size.

One socket for many connections: the UDP port is an :class:`~cobot_hmi.scanner.io_port.IoPort`,
shared by every originator of the process on the same local address, or (without one) the
originator's own. T→O is accepted on the connection ID we chose from the moment the Forward
Open leaves, and only from the target's address.

Bumpless takeover: every connection starts **idle**, and its command image is seeded from the
robot's actual outputs in the first T→O frame (and the bit input registers from an explicit
read of the O→T assembly where the target allows it: that read, done before the Forward Open,
is also what the first O→T packet carries), so switching to run changes nothing until someone
writes. O→T data given in the settings (``o2t_data``, ``scan --o2t-hex``) is never taken over:
every packet carries it until it is changed. The state is CONNECTED only once that first frame
has arrived.

A target sending T→O less often than the API it granted is reported once, and once again
when it keeps its grant (``scanner.t2o_pace``): ``on_slow_target`` and ``stats().slow_target``.

:class:`Originator` composes a few objects with one job each (``scanner.connection``), each given
only what it needs and each testable alone: the connection's ``ConnectionStatus`` (its state,
told to ``on_state``), an ``O2TSender`` (what O→T carries, the takeover), a ``T2OReceiver`` (the
port's consumer of T→O, the figures, the watchdog) and the ``ConnectionLifecycle`` (the port, the
supervisor, Forward Open and Close), which hands each open connection's ``Link`` to the other
two. The port calls the receiver itself: a T→O packet goes through no layer of the originator.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Generic, TypeVar, overload

from cobot_hmi.codec import CommandImage, Frame
from cobot_hmi.scanner.connection.lifecycle import ConnectionLifecycle
from cobot_hmi.scanner.connection.link import Link
from cobot_hmi.scanner.connection.o2t_send import O2TSender
from cobot_hmi.scanner.connection.originator_settings import (
    OriginatorSettings,
    fit_o2t_data,
    local_address_to,
)
from cobot_hmi.scanner.connection.state import (
    ConnectionState,
    ConnectionStats,
    ConnectionStatus,
    NotConnectedError,
    ReadOnlyError,
    StateCallback,
)
from cobot_hmi.scanner.connection.t2o_receive import (
    DataCallback,
    FrameCallback,
    SlowTargetCallback,
    T2OReceiver,
)
from cobot_hmi.scanner.io_port import IoPort

_T = TypeVar("_T")


class _ReadThrough(Generic[_T]):
    """An attribute of the originator that one of its parts keeps, read where it is kept (the
    originator copies no figure: the receiver counts, the sender holds the command image)."""

    __slots__ = ("_read",)

    def __init__(self, read: Callable[[Originator], _T]) -> None:
        self._read = read

    @overload
    def __get__(self, originator: None, owner: type[Originator]) -> _ReadThrough[_T]: ...

    @overload
    def __get__(self, originator: Originator, owner: type[Originator]) -> _T: ...

    def __get__(
        self, originator: Originator | None, owner: type[Originator]
    ) -> _T | _ReadThrough[_T]:
        return self if originator is None else self._read(originator)


class Originator:
    """One class 1 connection to one target. Several may share an :class:`IoPort` (one UDP
    socket of their local address) when they run on the port's event loop."""

    def __init__(
        self,
        settings: OriginatorSettings,
        *,
        on_frame: FrameCallback | None = None,
        on_state: StateCallback | None = None,
        on_data: DataCallback | None = None,
        on_slow_target: SlowTargetCallback | None = None,
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
        ``on_state(state, reason)``: each change of the connection's state.
        ``on_slow_target(slow)``: the target was found sending T→O slower than its grant (a
        ``SlowTarget``), or keeping it again (None), once each time (``scanner.t2o_pace``).
        ``io_port``: the UDP port to share (None: one of our own, opened on start and closed on
        stop). A ``ValueError`` when ``o2t_data`` does not fit the O→T size."""
        self.settings = settings
        self._status = ConnectionStatus(on_state)
        self._sender = O2TSender(settings, self._status)
        self._receiver = T2OReceiver(
            settings,
            seed=self._sender.seed,
            on_frame=on_frame,
            on_data=on_data,
            on_slow_target=on_slow_target,
        )
        self._lifecycle = ConnectionLifecycle(
            settings, self._status, self._sender, self._receiver, io_port=io_port
        )

    # The connection's state (its status), what O→T carries (the sender), what T→O brought and
    # its counters (the receiver), each read where it is kept.
    state = _ReadThrough[ConnectionState](lambda o: o._status.state)
    reason = _ReadThrough[str | None](lambda o: o._status.reason)
    on_state = _ReadThrough[StateCallback | None](lambda o: o._status.on_state)
    run = _ReadThrough[bool](lambda o: o._sender.run)
    command = _ReadThrough[CommandImage](lambda o: o._sender.command)
    o2t_data = _ReadThrough[bytes](lambda o: o._sender.o2t_data)
    """The O→T data the next packet carries (after the run/idle header)."""
    packets_out = _ReadThrough[int](lambda o: o._sender.packets_out)
    """O→T packets that left (counted by the cyclic pump as it sends them)."""
    latest = _ReadThrough[tuple[Frame, float] | None](lambda o: o._receiver.latest)
    """The last frame and its epoch receive time (T→O of the robot's layout)."""
    latest_data = _ReadThrough[tuple[bytes, float] | None](lambda o: o._receiver.latest_data)
    """The last T→O data and its epoch receive time (T→O of any other size, or raw)."""
    on_frame = _ReadThrough[FrameCallback | None](lambda o: o._receiver.on_frame)
    on_data = _ReadThrough[DataCallback | None](lambda o: o._receiver.on_data)
    on_slow_target = _ReadThrough[SlowTargetCallback | None](lambda o: o._receiver.on_slow_target)
    packets_in = _ReadThrough[int](lambda o: o._receiver.packets_in)
    gaps = _ReadThrough[int](lambda o: o._receiver.gaps)
    duplicates = _ReadThrough[int](lambda o: o._receiver.duplicates)
    late = _ReadThrough[int](lambda o: o._receiver.late)
    malformed = _ReadThrough[int](lambda o: o._receiver.malformed)
    stale = _ReadThrough[int](lambda o: o._receiver.stale)
    foreign = _ReadThrough[int](lambda o: o._receiver.foreign)
    frames = _ReadThrough[int](lambda o: o._receiver.frames)
    t2o_api_us = _ReadThrough[int | None](
        lambda o: o._receiver.link.t2o_api_us if o._receiver.link is not None else None
    )
    """The open connection's T→O packet interval (the RPI asked for until the reply grants
    one); None between connections. One int read: any thread (the health thread's clock)."""

    @property
    def io_port(self) -> IoPort | None:
        """The UDP port the connection uses (None before a start without a shared port)."""
        return self._lifecycle.port

    @property
    def _link(self) -> Link | None:
        """The open connection's negotiated numbers and sequence state (tests read them as a
        sniffer would see them)."""
        return self._receiver.link

    async def start(self) -> None:
        await self._lifecycle.start()

    async def stop(self) -> None:
        await self._lifecycle.stop()

    async def wait_connected(self, timeout_s: float) -> bool:
        return await self._status.wait_connected(timeout_s)

    def set_run(self, run: bool) -> None:
        """Run or idle (``ReadOnlyError`` input-only, ``NotConnectedError`` unconnected)."""
        self._sender.set_run(run)

    def set_o2t_data(self, data: bytes) -> int:
        """See :meth:`O2TSender.set_o2t_data`."""
        return self._sender.set_o2t_data(data)

    def set_command(self, image: CommandImage) -> int:
        """See :meth:`O2TSender.set_command`."""
        return self._sender.set_command(image)

    async def wait_sent(self, packets_out: int, timeout_s: float) -> bool:
        """See :meth:`O2TSender.wait_sent`."""
        return await self._sender.wait_sent(packets_out, timeout_s)

    def stats(self) -> ConnectionStats:
        receiver, status, lifecycle = self._receiver, self._status, self._lifecycle
        figures = receiver.interval_figures()
        latest = receiver.latest or receiver.latest_data
        link = receiver.link
        port = lifecycle.port
        # On a port of our own, every stray datagram is ours to count.
        own = port if lifecycle.owns_port and port is not None else None
        return ConnectionStats(
            state=status.state,
            reason=status.reason,
            packets_in=receiver.packets_in,
            packets_out=self._sender.packets_out,
            gaps=receiver.gaps,
            duplicates=receiver.duplicates,
            late=receiver.late,
            malformed=receiver.malformed + (own.malformed if own is not None else 0),
            interval_mean_ms=figures.mean_ms,
            interval_p99_ms=figures.p99_ms,
            interval_max_ms=figures.max_ms,
            last_frame_age_s=time.time() - latest[1] if latest is not None else None,
            connected_since=status.connected_since,
            stale=receiver.stale,
            foreign=receiver.foreign + (own.foreign if own is not None else 0),
            frames=receiver.frames,
            interval_p50_ms=figures.p50_ms,
            rpi_us=link.t2o_api_us if link is not None and link.o2t is not None else None,
            slow_target=receiver.slow_target if link is not None else None,
        )

    def pump_counters(self) -> dict[str, int]:
        """The cyclic pump's counters (``UdpEndpoint.counters``; the whole port's when it is
        shared), empty without an open port."""
        port = self._lifecycle.port
        return port.udp.counters() if port is not None and port.is_open else {}


__all__ = [
    "ConnectionState",
    "ConnectionStats",
    "NotConnectedError",
    "Originator",
    "OriginatorSettings",
    "ReadOnlyError",
    "fit_o2t_data",
    "local_address_to",
]
