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
"""

from __future__ import annotations

import asyncio
import logging
import time

from cobot_hmi.scanner.connection.lifecycle import ConnectionLifecycle
from cobot_hmi.scanner.connection.settings import OriginatorSettings, fit_o2t_data, local_address_to
from cobot_hmi.scanner.connection.state import (
    ConnectionState,
    ConnectionStats,
    NotConnectedError,
    ReadOnlyError,
)
from cobot_hmi.scanner.io_port import IoPort

log = logging.getLogger(__name__)


class Originator(ConnectionLifecycle):
    """One class 1 connection to one target. Several may share an :class:`IoPort` (one UDP
    socket of their local address) when they run on the port's event loop."""

    # ------------------------------------------------------------------ public interface

    @property
    def io_port(self) -> IoPort | None:
        """The UDP port the connection uses (None before a start without a shared port)."""
        return self._port

    async def start(self) -> None:
        if self._supervisor is None:
            self._stopping = False
            self._supervisor = asyncio.get_running_loop().create_task(
                self._supervise(), name="originator"
            )

    async def stop(self) -> None:
        self._stopping = True
        task, self._supervisor = self._supervisor, None
        # Cancel until the supervisor has really ended: on Python 3.11 ``asyncio.wait_for`` can
        # swallow a cancellation that lands as its inner awaitable completes (fixed in 3.12),
        # and a single cancel() would then leave stop() waiting for ever.
        while task is not None and not task.done():
            task.cancel()
            await asyncio.wait({task}, timeout=0.5)
        if task is not None and not task.cancelled() and task.exception() is not None:
            log.warning("supervisor ended with %r", task.exception())
        await self._teardown(forward_close=True)
        if self._owns_port and self._port is not None:
            self._port.close()
        self._set_state(ConnectionState.IDLE, None)

    def stats(self) -> ConnectionStats:
        figures = self._window.figures()
        latest = self.latest or self.latest_data
        link = self._link
        port = self._port
        # On a port of our own, every stray datagram is ours to count.
        own = port if self._owns_port and port is not None else None
        return ConnectionStats(
            state=self.state,
            reason=self.reason,
            packets_in=self.packets_in,
            packets_out=self.packets_out,
            gaps=self.gaps,
            duplicates=self.duplicates,
            late=self.late,
            malformed=self.malformed + (own.malformed if own is not None else 0),
            interval_mean_ms=figures.mean_ms,
            interval_p99_ms=figures.p99_ms,
            interval_max_ms=figures.max_ms,
            last_frame_age_s=time.time() - latest[1] if latest is not None else None,
            connected_since=self._connected_since,
            stale=self.stale,
            foreign=self.foreign + (own.foreign if own is not None else 0),
            frames=self.frames,
            interval_p50_ms=figures.p50_ms,
            rpi_us=link.t2o_api_us if link is not None and link.o2t is not None else None,
            slow_target=self._pace.slow if link is not None else None,
        )

    def pump_counters(self) -> dict[str, int]:
        """The cyclic pump's counters (``UdpEndpoint.counters``; the whole port's when it is
        shared), empty without an open port."""
        port = self._port
        return port.udp.counters() if port is not None and port.is_open else {}

    async def wait_connected(self, timeout_s: float) -> bool:
        if self.state is ConnectionState.CONNECTED:
            return True
        try:
            await asyncio.wait_for(self._connected_event.wait(), timeout_s)
        except TimeoutError:
            return False
        state: ConnectionState = self.state  # changed by the supervisor meanwhile
        return state is ConnectionState.CONNECTED


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
