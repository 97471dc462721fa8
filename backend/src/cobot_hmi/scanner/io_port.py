"""Layer: scanner (asyncio I/O, the originator role). Imports ``cobot_hmi.enip`` and the runtime
support (``udp_endpoint``); never the codec's frames, the emulator or the service.

The class 1 UDP port of an originator (issue 11, "Many connections, one socket"): one socket on
UDP 2222 of one local address, shared by every class 1 connection the process holds from that
address, as a PLC holds its connections to many adapters. A second socket on 2222 of the same
address cannot work (the kernel hands each datagram to one of them), so the connections are
told apart by connection ID (CIP Vol 2 §3-4: the consumer matches the 0x8002 item's
connection ID) and, per connection, by the producer's address (the consumer check of CIP Vol 2
§3-4: T→O comes from the target's address; anything else with the same ID is forged).

Every connection's O→T stream goes through the port's cyclic pump (``O2TStream``), each under a
tag of the port's own (two targets may well choose the same O→T connection ID).

The port keeps the pump's wake-ups right for all of its connections: at most every ``batch_s``
of the connection that wants the shortest batch (0, one per datagram, as soon as one connection
runs at an RPI of ``BATCH_PERIOD_S`` or more), and once after the shortest watchdog timeout of
silence on the whole socket. A port that brings more than ``PER_DATAGRAM_MAX_PER_S`` packets a
second (a cell of many robots) wakes at most every ``BUSY_BATCH_S`` instead of per datagram:
each wake-up of the thread costs more CPU than the few packets it serves (16 robots at RPI 10 ms
are 1600 wake-ups a second; on a 2-core VM a wake-up of the interpreter costs about 150 µs
of CPU whatever it does), while a frame still reaches the service within about an RPI and its
receive time is the kernel's either way. One reader cannot wait for a batch: a write's
confirmation, the robot's first frame showing the change. A connection whose O→T data changed
calls the port's ``hurry``: it reads per datagram for ``hurry_window_s`` (a few RPIs), then
batches again, so a write is confirmed as soon as on a quiet port.

After a wake-up only the connections that received something look at their T→O
(``t2o_batch_read``); every connection does after a wake-up for silence. A single connection
falling silent among busy ones is caught at its own O→T stream's fallback timer.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import random
from dataclasses import dataclass
from typing import Protocol

from cobot_hmi.enip import io
from cobot_hmi.enip.encapsulation import ENIP_UDP_PORT
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.udp_endpoint import UdpEndpoint

log = logging.getLogger(__name__)

RING_SLOTS = 4096
"""Received datagrams the pump holds for us: one port serves every robot of the cell, so a
stall of our thread (the GIL held by the web loop, the machine busy) lasting 1.3 s at 32 robots
at RPI 10 ms loses nothing (the pump's default, 256, held 80 ms of such a cell); 6 MiB of slots."""
RECEIVE_BUFFER_BYTES = 4 * 1024 * 1024
"""The socket's kernel receive buffer asked for: the kernel's default (about 200 KiB, some 160
datagrams) was the shorter of the two while the pump's own thread waited for a core; capped
by ``net.core.rmem_max``."""

RING_SHARE_PER_BATCH = 0.25
"""At most this share of the pump's receive ring fills between two reads of ours: the rest is
what a stall of our loop may last before the ring gives up its oldest datagrams (32 connections
at RPI 2 ms fill 4096 slots in 256 ms; a batch then leaves three quarters of that for a stall)."""


PER_DATAGRAM_MAX_PER_S = 500.0
"""Above this many T→O packets a second on the port (five robots at RPI 10 ms), connections
asking for their T→O at once are woken every ``BUSY_BATCH_S`` instead of per datagram."""
BUSY_BATCH_S = 0.010
"""The busy port's wake-up period: the service's default RPI (a frame reaches the stream and
the alarms at most 10 ms after it arrived; a write's confirmation does not wait: ``hurry``).
At 4 ms, 16 robots at RPI 10 ms cost the cyclic thread 250 wake-ups a second, at 10 ms 100."""
HURRY_MIN_S = 0.2
"""The shortest time a port reads per datagram after an O→T change (``hurry_window_s``)."""


def hurry_window_s(t2o_api_s: float) -> float:
    """How long a port reads per datagram after a connection's O→T data changed: the change's
    first frame comes within two RPIs and a robot's reaction; a slower one is read at the
    port's batch pace."""
    return max(HURRY_MIN_S, 8 * t2o_api_s)


class T2OConsumer(Protocol):
    """What a connection hands the port: where its T→O goes."""

    def t2o_packet(self, packet: io.IoPacket, arrived: float) -> None:
        """A T→O packet with this connection's ID from the target's address (``arrived``: the
        loop time the kernel received it)."""

    def t2o_foreign(self) -> None:
        """A datagram with this connection's ID from another address, or one from the target's
        address with an unknown connection ID: dropped, counted."""

    def t2o_malformed(self) -> None:
        """A datagram from the target's address that is no class 1 packet: dropped, counted."""

    def t2o_batch_read(self, now: float) -> None:
        """After a wake-up of the port that brought this connection T→O, and after every
        wake-up for silence (``now``: the loop time then, read once for every connection)."""


@dataclass(frozen=True, slots=True)
class _Route:
    source_host: str
    consumer: T2OConsumer
    batch_s: float
    silence_s: float
    packets_per_s: float


class IoPort:
    """One UDP socket (``local_host``:``udp_port``) and its cyclic pump, shared by every class 1
    connection of the process from that address. Create, open and use it on the event loop that
    runs its originators."""

    def __init__(self, local_host: str, udp_port: int = ENIP_UDP_PORT) -> None:
        self.local_host = local_host
        self.udp_port = udp_port
        self.foreign = 0
        """Datagrams with a connection ID no connection holds, from no target's address."""
        self.malformed = 0
        """Datagrams that are no class 1 packet, from no target's address."""
        self._udp: UdpEndpoint | None = None
        self._routes: dict[int, _Route] = {}
        self._by_source: dict[str, list[T2OConsumer]] = {}
        self._tags = itertools.count(1)
        self._rng = random.Random()
        self._watch: tuple[float, float] | None = None
        self._woken: dict[int, T2OConsumer] = {}
        """The connections that received T→O since the last wake-up's end, by connection ID."""
        self._hurry_until = 0.0
        self._hurry_timer: asyncio.TimerHandle | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        """The event loop the port was opened on (its timers run there)."""

    # ------------------------------------------------------------------ lifetime

    @property
    def is_open(self) -> bool:
        return self._udp is not None

    @property
    def udp(self) -> UdpEndpoint:
        """The socket and its pump (opened by :meth:`open`)."""
        if self._udp is None:
            raise OSError(f"UDP port {self.local_host}:{self.udp_port} is not open")
        return self._udp

    async def open(self) -> None:
        """Bind the socket and start the pump (again after a close); an ``OSError`` names the
        address that cannot be bound."""
        if self._udp is not None:
            return
        try:
            udp = UdpEndpoint(
                self.local_host,
                self.udp_port,
                self._received,
                receive_size=io.MAX_DATAGRAM + 1,
                on_batch=self._batch_read,
                ring_slots=RING_SLOTS,
                receive_buffer_bytes=RECEIVE_BUFFER_BYTES,
            )
        except OSError as error:
            raise OSError(f"cannot bind UDP {self.local_host}:{self.udp_port}: {error}") from None
        self._udp = udp
        self._loop = asyncio.get_running_loop()
        self._watch = None
        self._configure()

    def close(self) -> None:
        """Close the socket; the connections still routed here hear nothing more."""
        if self._hurry_timer is not None:
            self._hurry_timer.cancel()
            self._hurry_timer = None
        self._hurry_until = 0.0
        udp, self._udp = self._udp, None
        if udp is not None:
            udp.close()

    @property
    def batch_s(self) -> float | None:
        """How often the pump wakes us at most while T→O comes (0: per datagram), None
        before the port is open."""
        return self._watch[0] if self._watch is not None else None

    # ------------------------------------------------------------------ connections

    def new_connection_id(self) -> int:
        """A T→O connection ID (CIP Vol 1 §3-5.4.1: chosen by the originator for a
        point-to-point T→O) that no connection of this port holds."""
        while True:
            connection_id = self._rng.getrandbits(32)
            if connection_id and connection_id not in self._routes:
                return connection_id

    def new_tag(self) -> int:
        """A pump tag for one O→T stream, unique on this port."""
        return next(self._tags)

    def route(
        self,
        t2o_id: int,
        source_host: str,
        consumer: T2OConsumer,
        *,
        batch_s: float,
        silence_s: float,
        packets_per_s: float = 0.0,
    ) -> None:
        """T→O with ``t2o_id`` from ``source_host`` goes to ``consumer`` from now on (before the
        Forward Open leaves: the first T→O packet may come before its reply is read).
        ``batch_s``: how often the connection wants its T→O at most (0: at once).
        ``silence_s``: its watchdog timeout (0: none yet). ``packets_per_s``: how many T→O
        packets it brings (1 / API): the batch shortens as the port's connections add up, so a
        batch never fills more than ``RING_SHARE_PER_BATCH`` of the pump's receive ring."""
        old = self._routes.get(t2o_id)
        if old is not None and old.consumer is not consumer:
            raise ValueError(f"T→O connection ID 0x{t2o_id:08X} is routed already")
        if old is not None:
            self._forget_source(old)
        self._routes[t2o_id] = _Route(source_host, consumer, batch_s, silence_s, packets_per_s)
        self._by_source.setdefault(source_host, []).append(consumer)
        self._configure()

    def unroute(self, t2o_id: int) -> None:
        """T→O with ``t2o_id`` is foreign again."""
        route = self._routes.pop(t2o_id, None)
        if route is not None:
            self._forget_source(route)
            self._configure()

    def _forget_source(self, route: _Route) -> None:
        consumers = self._by_source.get(route.source_host)
        if consumers is not None:
            if route.consumer in consumers:
                consumers.remove(route.consumer)
            if not consumers:
                del self._by_source[route.source_host]

    @property
    def hurried(self) -> bool:
        """Reading per datagram for a write's confirmation (``hurry``)."""
        return self._hurry_timer is not None

    def hurry(self, window_s: float) -> None:
        """A connection's O→T data changed: read T→O per datagram for ``window_s`` from now
        (or longer, if a hurry is on already), so the change's confirmation is read as it
        arrives, not at the next batch. On the port's event loop."""
        loop = self._loop
        if loop is None or self._udp is None:  # not open: nothing to read
            return
        until = loop.time() + window_s
        if until <= self._hurry_until:
            return
        self._hurry_until = until
        if self._hurry_timer is not None:
            self._hurry_timer.cancel()
        self._hurry_timer = loop.call_at(until, self._hurry_over)
        self._configure()

    def _hurry_over(self) -> None:
        self._hurry_timer = None
        self._configure()

    def _configure(self) -> None:
        """The pump's wake-ups for the connections routed now (only when they change)."""
        udp = self._udp
        if udp is None:
            return
        routes = self._routes.values()
        batch_s = min((r.batch_s for r in routes), default=0.0)
        packets_per_s = sum(r.packets_per_s for r in routes)
        if batch_s == 0 and packets_per_s > PER_DATAGRAM_MAX_PER_S:
            batch_s = BUSY_BATCH_S
        if batch_s > 0 and packets_per_s > 0:
            batch_s = min(batch_s, RING_SLOTS * RING_SHARE_PER_BATCH / packets_per_s)
        if self._hurry_timer is not None:
            batch_s = 0.0
        silence_s = min((r.silence_s for r in routes if r.silence_s > 0), default=0.0)
        if self._watch != (batch_s, silence_s):
            self._watch = (batch_s, silence_s)
            udp.watch(True, batch_s, silence_s=silence_s)

    # ------------------------------------------------------------------ receiving

    def _received(self, data: bytes, addr: tuple[str, int], arrived: float) -> None:
        try:
            packet = io.decode_io(data)
        except EnipError:
            consumers = self._by_source.get(addr[0])
            if consumers:
                consumers[0].t2o_malformed()
            else:
                self.malformed += 1
            return
        route = self._routes.get(packet.connection_id)
        if route is not None and route.source_host == addr[0]:
            route.consumer.t2o_packet(packet, arrived)
            self._woken[packet.connection_id] = route.consumer
            return
        if route is not None:
            # The live connection ID from another address: forged, or a stray (the consumer
            # check, CIP Vol 2 §3-4). Counted on the connection it pretends to be.
            route.consumer.t2o_foreign()
            return
        consumers = self._by_source.get(addr[0])
        if consumers:
            consumers[0].t2o_foreign()
        else:
            self.foreign += 1

    def read_now(self) -> None:
        """Hand every T→O datagram received so far to its connection now, without waiting for
        the batch (a watchdog about to give its verdict judges what has arrived, not what the
        last batch read)."""
        if self._udp is not None:
            self._udp.drain()

    def _batch_read(self) -> None:
        woken = self._woken
        if woken:
            consumers = list(woken.values())
            woken.clear()
        else:  # nothing came: the pump's word of silence, every connection looks
            consumers = [route.consumer for route in self._routes.values()]
        loop = self._loop
        now = loop.time() if loop is not None else asyncio.get_running_loop().time()
        for consumer in consumers:
            try:
                consumer.t2o_batch_read(now)
            except Exception:
                log.exception("T→O batch callback failed")


__all__ = ["BUSY_BATCH_S", "IoPort", "T2OConsumer", "hurry_window_s"]
