"""Layer: emulator (asyncio I/O). Imports the codec, ``cobot_hmi.enip``, the emulator's own
modules and the runtime support (``udp_endpoint``); never the scanner or the service.

The target's class 1 I/O connections on UDP 2222 (CIP Vol 1 §3-4, Connection object; CIP Vol 2
§3-4, class 0/1 packets): T→O packets built ahead on each connection's drift-free RPI schedule
and handed to the cyclic pump, which sends each at its due time (as a periodic stream while the
robot's data holds still); O→T consumed by connection ID under the receive rules of
``enip.sequence`` (read at our wake-ups while a connection produces at a short RPI), run/idle
applied to the :class:`ProcessImage`, and a watchdog per connection (``o2t_watchdog``).
docs/protocol.md "Timing" says why the work is batched the way it is.
"""

from __future__ import annotations

import asyncio
import logging
import math
import random
import time
from collections.abc import Callable

from cobot_hmi.emulator.connections import ConnectionInfo, ConnectionKind, IoConnection
from cobot_hmi.emulator.counters import TargetCounters
from cobot_hmi.emulator.faults import TargetFaults
from cobot_hmi.emulator.o2t_watchdog import O2TWatchdogs
from cobot_hmi.emulator.process_image import HoldsStill, ProcessImage
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.enip import io
from cobot_hmi.enip.connection_manager import ForwardOpenRequest
from cobot_hmi.enip.epath import ConnectionPath
from cobot_hmi.enip.errors import EnipError
from cobot_hmi.enip.sequence import DUPLICATE, STALE
from cobot_hmi.udp_endpoint import BATCH_PERIOD_S, QueueFullError, UdpEndpoint

log = logging.getLogger(__name__)


TICK_READ_MAX_RPI_US = round(BATCH_PERIOD_S * 1e6)
"""While a connection produces T→O at a shorter RPI, we wake once per
``TargetSettings.batch_period_s`` (not per packet): each wake-up reads the O→T packets that came
meanwhile (with their kernel receive times) and builds the next batch of T→O packets (or hands
the pump new data for its periodic stream). At this RPI or longer we wake once per packet, and
O→T is read as it arrives."""
HORIZON_MARGIN_S = 0.001
"""How far past the next wake-up T→O is built ahead: a wake-up that comes up to this late still
finds the pump with a packet to send."""
STILL_MARGIN_S = 0.0002
"""A wake-up for the robot's next change of its own comes this much after it: one a hair early
(the loop's and the epoch clocks read apart) would find the old frame and wait a whole RPI."""
STILL_LONGEST_S = 1.0
"""The longest a wake-up waits for the robot's next change of its own."""


class IoConnections:
    """The class 1 engine: the connection table, the UDP socket and its cyclic pump, the
    schedule of our wake-ups. ``table`` is shared with the owner (the target) for reading."""

    def __init__(
        self,
        settings: TargetSettings,
        process_image: ProcessImage,
        t2o_data: Callable[[float], bytes],
        consume_o2t: Callable[[bytes, float], None],
        *,
        faults: TargetFaults,
        counters: TargetCounters,
        table: dict[int, IoConnection],
    ) -> None:
        self.settings = settings
        self.process_image = process_image
        self._t2o_data = t2o_data
        """The T→O assembly's data at an epoch time (``AssemblyObject.t2o_data``)."""
        self._consume_o2t = consume_o2t
        self._still_until = (
            process_image.frame_still_until_s if isinstance(process_image, HoldsStill) else None
        )
        """Until when the robot's frame holds by itself (epoch seconds), if it can tell."""
        """New O→T data of the owner in run, at an epoch time (``AssemblyObject.consume_o2t``)."""
        self.faults = faults
        self.counters = counters
        self._by_o2t = table
        self._rng = random.Random(settings.seed)
        self._udp: UdpEndpoint | None = None
        self._ticker: asyncio.Handle | None = None
        self._tick_due = 0.0
        self._wake_period_s: float | None = None
        self.udp_port = settings.udp_port
        self._watchdogs = O2TWatchdogs(
            table,
            counters,
            udp=lambda: self._udp,
            wake_period_s=lambda: self._wake_period_s,
            read_due=self._read_due_o2t,
            close=self.close,
        )

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> None:
        """Bind the class 1 UDP socket (``OSError`` if the address is taken)."""
        udp = UdpEndpoint(
            self.settings.host,
            self.settings.udp_port,
            self._o2t_received,
            receive_size=io.MAX_DATAGRAM + 1,
            kernel_timestamps=True,
            on_batch=self._watchdogs.woke,
        )
        udp.watch(True)
        self._udp = udp
        self.udp_port = udp.port

    def close_all(self, reason: str) -> None:
        """Close every connection, without applying the idle behaviour (the target stops)."""
        for conn in list(self._by_o2t.values()):
            self.close(conn, reason, idle=False)

    def shutdown(self) -> None:
        """Cancel every timer and close the socket."""
        for conn in self._by_o2t.values():
            conn.cancel_timers()
        if self._ticker is not None:
            self._ticker.cancel()
            self._ticker = None
        if self._udp is not None:
            self._udp.close()
            self._udp = None

    # ------------------------------------------------------------------ the table

    def table(self) -> list[IoConnection]:
        return list(self._by_o2t.values())

    def owner_present(self) -> bool:
        """Whether an exclusive owner holds the O→T assembly now."""
        return any(c.kind is ConnectionKind.OWNER for c in self._by_o2t.values())

    def open(
        self,
        kind: ConnectionKind,
        request: ForwardOpenRequest,
        path: ConnectionPath,
        peer: tuple[str, int],
    ) -> IoConnection:
        """Add the connection a Forward Open was admitted for, and start producing: the first
        T→O packet at once (after the reply is written), then every RPI; the watchdog from
        the open on."""
        o2t_id = self._new_connection_id()
        t2o_id = request.t2o_connection_id or self._new_connection_id()
        loop = asyncio.get_running_loop()
        conn = IoConnection(
            kind=kind,
            o2t_id=o2t_id,
            t2o_id=t2o_id,
            triplet=request.triplet,
            peer=peer,
            o2t_rpi_us=request.o2t_rpi_us,
            t2o_rpi_us=request.t2o_rpi_us,
            timeout_multiplier=request.timeout_multiplier,
            o2t_connection_size=request.o2t_params.size_bytes,
            t2o_connection_size=request.t2o_params.size_bytes,
            path=path,
            opened_at=time.time(),
            last_rx=loop.time(),
        )
        self._by_o2t[o2t_id] = conn
        conn.t2o_last_due = loop.time() - conn.t2o_rpi_us / 1e6
        self._update_schedule()
        log.info("%s connection open: O→T 0x%08X T→O 0x%08X to %s:%d", kind, o2t_id, t2o_id, *peer)
        return conn

    def _new_connection_id(self) -> int:
        while True:
            candidate = self._rng.getrandbits(32)
            if (
                candidate
                and candidate not in self._by_o2t
                and all(c.t2o_id != candidate for c in self._by_o2t.values())
            ):
                return candidate

    def connections(self) -> list[ConnectionInfo]:
        """A snapshot of every connection (the counts of streamed packets brought up to date,
        in ``counters`` too)."""
        self._sync_streamed()
        return [c.info() for c in self._by_o2t.values()]

    def pump_counters(self) -> dict[str, int]:
        """The class 1 socket's cyclic pump (``UdpEndpoint.counters``): T→O packets sent and
        send errors, O→T received, its wake-ups, the latest send behind its due time."""
        return self._udp.counters() if self._udp is not None else {}

    def close(self, conn: IoConnection, reason: str, *, idle: bool = True) -> None:
        """Remove a connection: its packets built ahead do not go out; an owner in run leaves
        the outputs to the idle behaviour (unless ``idle`` is false); listen-only connections
        go with the last connection producing what they listen to."""
        if self._by_o2t.pop(conn.o2t_id, None) is None:
            return
        log.info("%s connection 0x%08X closed: %s", conn.kind, conn.o2t_id, reason)
        if conn.t2o_streaming:
            self._stop_stream(conn)
        conn.cancel_timers()
        if self._udp is not None:
            self._udp.cancel(conn.o2t_id)  # what was built ahead for it does not go out
        self._update_schedule()
        if idle and conn.kind is ConnectionKind.OWNER and conn.run:
            conn.run = False
            self.process_image.outputs_idle(time.time())
            self.process_image_changed()
        if conn.produces and not any(c.produces for c in self._by_o2t.values()):
            # Listen-only connections follow the data they listen to (CIP: 0x0119).
            for other in list(self._by_o2t.values()):
                self.close(other, "the last non-listen-only connection closed", idle=idle)

    # ------------------------------------------------------------------ class 1 engine

    def _update_schedule(self) -> None:
        """The connections changed: how often we wake, and whether O→T wakes us."""
        shortest_us = min((c.t2o_rpi_us for c in self._by_o2t.values()), default=None)
        udp = self._udp
        if self._ticker is not None:
            self._ticker.cancel()
            self._ticker = None
        if shortest_us is None:  # no connection left
            if udp is not None:
                udp.watch(True)
            self._wake_period_s = None
            return
        per_packet = shortest_us >= TICK_READ_MAX_RPI_US
        self._wake_period_s = (
            shortest_us / 1e6
            if per_packet
            else max(shortest_us / 1e6, self.settings.batch_period_s)
        )
        if udp is not None:
            # In batches, the pump wakes us once O→T has been silent for the shortest timeout:
            # a watchdog verdict then comes at once, not at the next batch.
            timeouts = (c.timeout_s for c in self._by_o2t.values())
            udp.watch(per_packet, silence_s=0.0 if per_packet else min(timeouts))
        self._watchdogs.arm()
        self._tick_due = asyncio.get_running_loop().time()
        self._ticker = asyncio.get_running_loop().call_soon(self._tick)

    def _read_due_o2t(self) -> None:
        udp = self._udp
        if udp is not None and not udp.watching:
            udp.drain()

    def _tick(self) -> None:
        """One wake-up of the class 1 engine: read the O→T that came meanwhile, then build every
        connection's T→O packets up to the next wake-up (plus a margin) and queue them.

        A plain timer callback, not a task. Each packet's frame is computed for the instant it
        is due (the robot model takes the time as an argument), in due order across
        connections, so the model only ever moves forward. The next wake-up is the last queued
        packet's due time (half an RPI before, in batches): at RPIs of ``BATCH_PERIOD_S`` or
        longer, one packet ahead, as a controller prepares the next cycle's data."""
        self._ticker = None
        period_s = self._wake_period_s
        if period_s is None or self._udp is None:
            return
        self._read_due_o2t()
        loop = asyncio.get_running_loop()
        now = loop.time()
        self._watchdogs.judge_batch_watched(now, now - self._tick_due)
        horizon = now + period_s + HORIZON_MARGIN_S
        try:
            self._queue_t2o_until(horizon, now)
        except Exception:  # a robot bug must not stop the connections' heartbeat
            self.counters.internal_errors += 1
            log.exception("T→O production failed")
        if not self._by_o2t:
            return
        queued = [c for c in self._by_o2t.values() if not c.t2o_streaming]
        if not queued:
            self._tick_due = self._streams_tick_due(now, period_s)
        else:
            first = min(queued, key=lambda c: c.t2o_last_due)
            wake_at = first.t2o_last_due
            if period_s > first.t2o_rpi_us / 1e6:
                # Batches: wake while the last packet still waits in the pump, so its queue
                # never runs empty (an empty pump would wake for O→T, then for our new batch).
                wake_at -= first.t2o_rpi_us / 2e6
            self._tick_due = max(now + period_s / 2, wake_at)
        self._ticker = loop.call_at(self._tick_due, self._tick)

    def _streams_tick_due(self, now: float, period_s: float) -> float:
        """Streams only (the pump needs nothing from us): the next wake-up, to read the robot
        again. Once per RPI, or, while O→T wakes us as it comes (so no command waits for our
        wake-ups), when the robot's frame changes by itself (a monitoring refresh, a step of
        the program, a timed state change): until then a wake-up would only find the frame the
        stream already carries. A change is thus read when it happens, not up to an RPI late."""
        due = now + period_s
        still_until = self._still_until
        udp = self._udp
        if still_until is None or udp is None or not udp.watching:
            return due
        held = still_until() - (time.time() - now) + STILL_MARGIN_S
        return min(max(due, held), now + STILL_LONGEST_S)

    def _queue_t2o_until(self, horizon: float, now: float) -> None:
        """Queue each producing connection's packets due up to ``horizon``, earliest first."""
        epoch_minus_loop = time.time() - now
        # A robot whose data refreshes on its own period (the real controller's monitoring
        # values: about every 100 ms) is read once per wake-up, its I/O and state at most one
        # wake-up late; one whose every instant differs, once per packet.
        tick_data = self._t2o_data(now + epoch_minus_loop) if self._reads_per_tick() else None
        stream_data = None if self.faults.per_packet() else tick_data
        for conn in self._by_o2t.values():
            if stream_data is not None:
                self._stream_t2o(conn, stream_data, now)
            elif conn.t2o_streaming:
                self._stop_stream(conn)
        producers = [c for c in self._by_o2t.values() if not c.t2o_streaming]
        while producers:
            # A target slower than its grant (the interval fault) sends every period, not RPI.
            period = self.faults.t2o_period_s
            conn = min(producers, key=lambda c: c.t2o_last_due + period(c.t2o_rpi_us))
            period_s = period(conn.t2o_rpi_us)
            due = conn.t2o_last_due + period_s
            if due > horizon:
                return
            if due < now - period_s:
                # Far behind (a stalled loop): skip the packets missed, never burst, and stay on
                # the schedule's grid, as a controller producing on its own clock does (a frame
                # for the late ``now`` put the robot's instants off it, and the health engine
                # takes the spacing of samples as whole periods).
                due += math.floor((now - due) / period_s) * period_s
            conn.t2o_last_due = due
            self._queue_t2o(conn, due, due + epoch_minus_loop, rebuild=False, data=tick_data)

    def _stream_t2o(self, conn: IoConnection, data: bytes, now: float) -> None:
        """T→O of ``conn`` as a periodic stream of the pump carrying ``data``: started after
        the last packet queued (the sequence numbers run on), or given the new data."""
        udp = self._udp
        if udp is None:
            return
        if conn.t2o_streaming:
            if data is not conn.t2o_stream_data:
                udp.replace_periodic(conn.o2t_id, io.encode_io(conn.t2o_id, 0, 0, data))
                conn.t2o_stream_data = data
            return
        period_s = conn.t2o_rpi_us / 1e6
        first_due = max(conn.t2o_last_due + period_s, now - period_s)
        first_seq = (conn.t2o_encap_seq + 1) & 0xFFFFFFFF
        try:
            udp.send_every(
                conn.o2t_id,
                first_due,
                period_s,
                io.encode_io(conn.t2o_id, 0, 0, data),
                conn.peer,
                (io.ENCAP_SEQ_OFFSET, first_seq),
                (io.CIP_SEQ_OFFSET, (conn.t2o_cip_seq + 1) & 0xFFFF),
            )
        except QueueFullError:
            return  # every stream of the pump is taken: this one stays packet by packet
        conn.t2o_streaming = True
        conn.t2o_stream_data = data
        conn.t2o_stream_first_seq = first_seq
        conn.t2o_stream_counted = 0
        conn.t2o_last_kind = "streamed"

    def _count_streamed(self, conn: IoConnection, next_seq: int) -> None:
        sent = (next_seq - conn.t2o_stream_first_seq) & 0xFFFFFFFF
        delta = sent - conn.t2o_stream_counted
        conn.t2o_stream_counted = sent
        conn.packets_out += delta
        self.counters.t2o_sent += delta

    def _stop_stream(self, conn: IoConnection) -> None:
        """Back to packet by packet: the queue goes on where the stream stopped."""
        udp = self._udp
        conn.t2o_streaming = False
        conn.t2o_stream_data = None
        state = udp.stop_periodic(conn.o2t_id) if udp is not None else None
        if state is None:
            return
        next_seq, next_cip, next_due = state
        self._count_streamed(conn, next_seq)
        conn.t2o_encap_seq = (next_seq - 1) & 0xFFFFFFFF
        conn.t2o_cip_seq = (next_cip - 1) & 0xFFFF
        conn.t2o_last_due = next_due - conn.t2o_rpi_us / 1e6
        conn.t2o_last_kind = "none"

    def _sync_streamed(self) -> None:
        udp = self._udp
        if udp is None:
            return
        for conn in self._by_o2t.values():
            if conn.t2o_streaming:
                state = udp.periodic_next(conn.o2t_id)
                if state is not None:
                    self._count_streamed(conn, state[0])

    def _reads_per_tick(self) -> bool:
        return self.process_image.data_period_s > 0

    def _queue_t2o(
        self,
        conn: IoConnection,
        due: float,
        epoch_s: float,
        *,
        rebuild: bool,
        data: bytes | None = None,
    ) -> None:
        """Build the T→O packet due at loop time ``due`` (the frame for ``epoch_s``, unless
        ``data`` is given) and hand it to the pump. ``rebuild``: the packet replaces one taken
        back (same sequence numbers, same fault verdict; the fault draws and counters were made
        when it was first built)."""
        faults = self.faults
        udp = self._udp
        if udp is None:
            return
        if faults.t2o_silent and not rebuild:
            conn.t2o_last_kind = "none"
            return
        if data is None:
            data = self._t2o_data(epoch_s)
        if not rebuild:
            conn.t2o_encap_seq = (conn.t2o_encap_seq + 1) & 0xFFFFFFFF
            conn.t2o_cip_seq = (conn.t2o_cip_seq + 1) & 0xFFFF
        packet = io.encode_io(conn.t2o_id, conn.t2o_encap_seq, conn.t2o_cip_seq, data)
        if rebuild:
            kind = conn.t2o_last_kind
        elif faults.t2o_drop_percent and self._rng.random() * 100.0 < faults.t2o_drop_percent:
            self.counters.t2o_dropped += 1
            kind = "dropped"
        elif faults.t2o_corrupt_count > 0:
            faults.t2o_corrupt_count -= 1
            self.counters.t2o_corrupted += 1
            kind = "corrupt"
        else:
            kind = "sent"
        conn.t2o_last_kind = kind
        if kind == "dropped":
            return
        if kind == "corrupt":
            packet = packet[: len(packet) // 2]  # truncated: the length fields no longer hold
        if not rebuild:
            conn.packets_out += 1
            self.counters.t2o_sent += 1
        udp.send_at(due + faults.t2o_delay_ms / 1e3, packet, conn.peer, conn.o2t_id)

    def process_image_changed(self) -> None:
        """The robot changed outside the cycle (a command applied, a control API action): take
        back each connection's last packet built ahead, if it has not left, and build it again.

        Only the last: the model has moved on to its instant, so earlier packets cannot be
        built again, and they describe instants before the change anyway. At RPIs of
        ``BATCH_PERIOD_S`` or longer the last is the only one: the change is in the next
        packet."""
        udp = self._udp
        if udp is None:
            return
        now = asyncio.get_running_loop().time()
        epoch_minus_loop = time.time() - now
        if self.faults.per_packet() and any(c.t2o_streaming for c in self._by_o2t.values()):
            # A fault came on since the last wake-up (a silence, say): the streams stop now,
            # never to carry the change, and the packets up to the next wake-up are built
            # under the fault (a silent target had sent the new outputs until that wake-up).
            for conn in self._by_o2t.values():
                if conn.t2o_streaming:
                    self._stop_stream(conn)
            if self._wake_period_s is not None:
                self._queue_t2o_until(now + self._wake_period_s + HORIZON_MARGIN_S, now)
            if self._ticker is not None:
                # The wake-up waited for the robot's next change (the streams needed nothing):
                # the queue just built lasts one wake period, so the next must come by then.
                self._ticker.cancel()
                self._ticker = asyncio.get_running_loop().call_soon(self._tick)
            return
        for conn in self._by_o2t.values():
            if conn.t2o_streaming:
                self._stream_t2o(conn, self._t2o_data(now + epoch_minus_loop), now)
                continue
            if conn.t2o_last_kind not in ("sent", "corrupt"):
                continue
            due = conn.t2o_last_due
            count, _ = udp.cancel(conn.o2t_id, due + self.faults.t2o_delay_ms / 1e3)
            if count:
                self._queue_t2o(conn, due, due + epoch_minus_loop, rebuild=True)
        self._tick_sooner(now)

    def _tick_sooner(self, now: float) -> None:
        """The robot changed outside the cycle: while only streams run, the wake-up for its
        next change of its own may now be due sooner (a program started, a reset)."""
        period_s, ticker = self._wake_period_s, self._ticker
        if ticker is None or period_s is None:
            return
        if not all(c.t2o_streaming for c in self._by_o2t.values()):
            return
        due = self._streams_tick_due(now, period_s)
        if due < self._tick_due:
            ticker.cancel()
            self._tick_due = due
            self._ticker = asyncio.get_running_loop().call_at(due, self._tick)

    def _o2t_received(self, data: bytes, addr: tuple[str, int], arrived: float) -> None:
        """One O→T datagram, ``arrived`` at that loop time (the kernel's receive time)."""
        counters = self.counters
        try:
            packet = io.decode_io(data)
        except EnipError:
            counters.udp_malformed += 1
            return
        conn = self._by_o2t.get(packet.connection_id)
        if conn is None or addr[0] != conn.peer[0]:
            counters.udp_unknown_connection += 1
            return
        owner = conn.kind is ConnectionKind.OWNER
        payload = packet.payload
        if owner and (packet.cip_seq is None or len(payload) != self.settings.o2t_size + 4):
            counters.udp_malformed += 1
            return
        # The receive rules, the same as the originator's (enip.sequence, CIP Vol 2 §3-4.2):
        # stale packets change nothing and do not feed the watchdog; duplicates do, and carry
        # no new data; a CIP count that went backwards is stale, never applied.
        verdict = conn.sequence.accept(packet.encap_seq, packet.cip_seq)
        if verdict is STALE:
            counters.udp_stale += 1
            return
        conn.last_rx = max(conn.last_rx, arrived)
        conn.packets_in += 1
        if verdict is DUPLICATE:
            conn.duplicates += 1
            counters.udp_duplicates += 1
            return
        conn.o2t_gaps += conn.sequence.missed
        if not owner:
            return  # a heartbeat: alive, nothing to apply
        now = conn.last_rx
        if conn.last_o2t_at is not None:
            conn.o2t_intervals_ms.append((now - conn.last_o2t_at) * 1e3)
        conn.last_o2t_at = now
        run, command = io.split_run_idle(payload)
        if command != conn.o2t_data:
            if conn.o2t_data is not None:
                conn.o2t_data_changes += 1
            conn.o2t_data = command
        if run:
            conn.run = True
            if command != conn.last_applied:
                conn.last_applied = command
                self._consume_o2t(command, time.time())
                self.process_image_changed()
        elif conn.run:
            conn.run = False
            conn.last_applied = None
            self.process_image.outputs_idle(time.time())
            self.process_image_changed()


__all__ = ["HORIZON_MARGIN_S", "TICK_READ_MAX_RPI_US", "IoConnections"]
