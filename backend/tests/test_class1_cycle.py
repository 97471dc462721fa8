"""The class 1 cycle's machinery (packets built ahead, sent by the cyclic pump, our own
wake-ups once per batch), functionally: the O→T stream (one packet per RPI from the pump, several
per wake-up of ours, changes rebuilt into the next packet with unbroken sequence numbers), the
target reading O→T at its wake-ups or as it arrives depending on the RPI, packets read late
keeping their arrival time, and both watchdogs surviving a stall of the event loop itself.
Deadlines are generous: nothing here asserts a timing figure.
"""

from __future__ import annotations

import asyncio
import functools
import itertools
import socket
import time

import pytest

from cobot_hmi.codec import command_from_json
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import TICK_READ_MAX_RPI_US, Target
from cobot_hmi.enip import io
from cobot_hmi.enip.encapsulation import ENIP_UDP_PORT
from cobot_hmi.scanner.o2t_stream import O2TStream, on_rpi_grid
from cobot_hmi.scanner.originator import ConnectionState, Originator, OriginatorSettings
from cobot_hmi.udp_endpoint import UdpEndpoint
from waiting import WAIT_DEADLINE_S, eventually

pytestmark = pytest.mark.both_pumps  # conftest: native and pure-Python pump
DEADLINE_S = WAIT_DEADLINE_S


# --------------------------------------------------------------------------- O→T stream


class Receiver:
    """A UDP endpoint collecting ``(data, arrival loop time)``."""

    def __init__(self, host: str) -> None:
        self.packets: list[tuple[bytes, float]] = []
        self.endpoint = UdpEndpoint(
            host, 0, lambda data, addr, at: self.packets.append((data, at)), receive_size=1501
        )
        self.endpoint.watch(True)
        self.addr = (host, self.endpoint.port)

    def close(self) -> None:
        self.endpoint.close()


def sequences(packets: list[tuple[bytes, float]]) -> list[tuple[int, int | None, bytes]]:
    decoded = [io.decode_io(data) for data, _ in packets]
    return [(p.encap_seq, p.cip_seq, p.payload) for p in decoded]


async def test_stream_sends_from_the_next_rpi_tick_then_every_rpi_waking_once_per_batch(
    plc_host: str, robot_host: str
) -> None:
    """At RPI 2 ms the packets leave from the pump: one each RPI from the grid's next tick,
    while we wake only for the fallback timer (no T→O here), several packets per wake-up."""
    receiver = Receiver(robot_host)
    sender = UdpEndpoint(plc_host, 0, lambda *_: None, receive_size=1501)
    stream = O2TStream(
        sender, 7, receiver.addr, 0.002, lambda: io.encode_io(7, 0, 0, b"\x00" * 20, 1)
    )
    try:
        stream.start()
        await eventually(lambda: len(receiver.packets) >= 1)
        await eventually(lambda: len(receiver.packets) >= 100)
        stream.stop()
        await asyncio.sleep(0.05)
        count = len(receiver.packets)
        await asyncio.sleep(0.05)
        assert len(receiver.packets) == count, "stopped: the queued packets were taken back"
    finally:
        sender.close()
        receiver.close()
    seqs = sequences(receiver.packets)
    assert [e for e, _, _ in seqs] == list(range(1, count + 1)), "one per slot, none skipped"
    assert stream.timer_wakeups * 4 <= count, "several packets per wake-up of ours"
    arrivals = [at for _, at in receiver.packets]
    span_s = arrivals[-1] - arrivals[0]
    assert span_s >= (count - 1) * 0.002 * 0.5, "paced at the RPI, not sent in bursts"


def test_the_rpi_grid_is_the_next_whole_number_of_rpis() -> None:
    """Exact in nanoseconds: streams of one RPI started at scattered instants get the same
    ticks, and a start on a tick keeps it."""
    for rpi_s in (0.002, 0.01, 0.0125, 0.1):
        period_ns = round(rpi_s * 1e9)
        for now in (1234.5678912, 98765.000001, 5.0, 0.0):
            due = on_rpi_grid(now, rpi_s)
            due_ns = round(due * 1e9)
            assert due_ns % period_ns == 0
            assert 0 <= due_ns - round(now * 1e9) < period_ns
            assert on_rpi_grid(due, rpi_s) == due, "a tick is its own next tick"


async def test_streams_of_one_rpi_leave_on_one_phase_one_wake_up_for_all(
    plc_host: str, robot_host: str
) -> None:
    """Eight connections' streams at RPI 10 ms, started at scattered instants, are due on the
    same ticks: the pump sends them in one wake-up per RPI, not one per packet (a late
    wake-up only gathers more packets, so a busy machine cannot fail this)."""
    receiver = Receiver(robot_host)
    sender = UdpEndpoint(plc_host, 0, lambda *_: None, receive_size=1501)
    streams = [
        O2TStream(
            sender,
            tag,
            receiver.addr,
            0.01,
            functools.partial(io.encode_io, tag, 0, 0, bytes(20), 1),
        )
        for tag in range(1, 9)
    ]
    try:
        for stream in streams:
            stream.start()
            await asyncio.sleep(0.0013)  # scattered starts
        dues = set()
        for tag in range(1, 9):
            following = sender.periodic_next(tag)
            assert following is not None
            dues.add(round(following[2] * 1e9) % 10_000_000)
        assert dues == {0}, "every stream on the 10 ms grid"
        before = sender.counters()
        await eventually(lambda: sender.counters()["sent"] - before["sent"] >= 400)
        after = sender.counters()
    finally:
        for stream in streams:
            stream.stop()
        sender.close()
        receiver.close()
    sent = after["sent"] - before["sent"]
    wakeups = after["wakeups"] - before["wakeups"]
    assert wakeups <= sent / 4, f"{wakeups} wake-ups for {sent} packets of 8 streams"


async def test_the_fallback_waits_one_watchdog_timeout_after_the_last_read(
    plc_host: str, robot_host: str
) -> None:
    """Given the connection's timeout, the fallback timer stays quiet while T→O is read (it
    moves itself on once per timeout instead of every few wake-ups) and looks once T→O stops,
    never before the timeout has passed since the last read (the watchdog's verdict is due then,
    and a look earlier is a wake-up for nothing). A busy machine may hold the reads back longer
    than the timeout: a look after such a gap is due, one sooner never is."""
    receiver = Receiver(robot_host)
    sender = UdpEndpoint(plc_host, 0, lambda *_: None, receive_size=1501)
    loop = asyncio.get_running_loop()
    looks: list[float] = []
    reads: list[float] = []
    watchdog_s = 0.15
    stream = O2TStream(
        sender,
        8,
        receiver.addr,
        0.01,
        lambda: io.encode_io(8, 0, 0, b"\x00" * 20, 1),
        on_timer=lambda now, lag_s: looks.append(now),
        watchdog_s=watchdog_s,
    )

    def read() -> None:
        stream.t2o_read()
        reads.append(loop.time())

    started = loop.time()
    try:
        stream.start()
        reading_until = loop.time() + 4 * watchdog_s
        while loop.time() < reading_until:  # T→O read every RPI, as a steady stream is
            read()
            await asyncio.sleep(0.01)
        read()
        looks_while_read = len(looks)
        await eventually(lambda: len(looks) > looks_while_read)
    finally:
        stream.stop()
        sender.close()
        receiver.close()
    longest_gap_s = max(b - a for a, b in itertools.pairwise([reads[0], *reads]))
    if longest_gap_s < watchdog_s - 1e-3:
        assert looks_while_read == 0, "no look while T→O is read every RPI"
    for look in looks:
        last_read = max((r for r in reads if r <= look), default=started)
        assert look - last_read >= watchdog_s - 1e-3, "not before the timeout since the last read"
    assert looks[-1] >= reads[-1] + watchdog_s - 1e-3, "a look once T→O stopped"


async def test_rebuild_puts_the_change_in_the_next_packet_with_the_same_numbers(
    plc_host: str, robot_host: str
) -> None:
    """A change takes back every packet built ahead and builds it again: the sequence numbers
    run on without a gap or a repeat, and once a packet carries the change every later one does."""
    receiver = Receiver(robot_host)
    sender = UdpEndpoint(plc_host, 0, lambda *_: None, receive_size=1501)
    payload = [b"old!"]
    stream = O2TStream(
        sender, 9, receiver.addr, 0.002, lambda: io.encode_io(9, 0, 0, payload[0], 1)
    )
    try:
        stream.start()
        await eventually(lambda: len(receiver.packets) >= 20)
        payload[0] = b"new!"
        stream.rebuild()
        await eventually(lambda: any(d.endswith(b"new!") for d, _ in receiver.packets))
        await eventually(lambda: len(receiver.packets) >= 60)
        stream.stop()
    finally:
        sender.close()
        receiver.close()
    seqs = sequences(receiver.packets)
    encaps = [e for e, _, _ in seqs]
    assert encaps == list(range(1, len(encaps) + 1))
    cips = [c for _, c, _ in seqs]
    assert cips == list(range(1, len(cips) + 1))
    payloads = [p[-4:] for _, _, p in seqs]
    first_new = payloads.index(b"new!")
    assert all(p == b"new!" for p in payloads[first_new:])


# --------------------------------------------------------------------------- target and scanner


async def held(
    target: Target, robot_host: str, plc_host: str, rpi_us: int, **changes: object
) -> Originator:
    settings = OriginatorSettings(
        robot_host=robot_host, tcp_port=target.tcp_port, local_host=plc_host, rpi_us=rpi_us
    )
    originator = Originator(settings, **changes)  # type: ignore[arg-type]
    await originator.start()
    assert await originator.wait_connected(DEADLINE_S)
    return originator


@pytest.mark.parametrize(
    "rpi_us", [2_000, TICK_READ_MAX_RPI_US + 10_000], ids=["read-at-ticks", "read-on-arrival"]
)
async def test_commands_reach_the_robot_whichever_way_o2t_is_read(
    target: Target, robot: StaticRobot, robot_host: str, plc_host: str, rpi_us: int
) -> None:
    originator = await held(target, robot_host, plc_host, rpi_us)
    try:
        image = command_from_json({"controlbox_do": {"3": True}}, base=originator.command)
        originator.set_command(image)
        originator.set_run(True)
        await eventually(lambda: robot.command_image() == image)
        await eventually(
            lambda: originator.latest is not None and originator.latest[0].controlbox_do[3]
        )
        assert originator.state is ConnectionState.CONNECTED
        (info,) = target.connections()
        assert info.run is True
        assert info.o2t_gaps == 0
    finally:
        await originator.stop()
    await eventually(lambda: target.connections() == [])


async def test_both_watchdogs_wait_out_a_stall_of_their_own_loop(
    target: Target, robot_host: str, plc_host: str
) -> None:
    """Scanner and target share this loop; a synchronous stall far longer than both watchdogs
    (RPI 5 ms × 16 = 80 ms) silences both directions, but only because the loop itself stood
    still: once it runs again, packets flow and neither side declares a timeout."""
    states: list[ConnectionState] = []
    originator = await held(
        target, robot_host, plc_host, 5_000, on_state=lambda state, reason: states.append(state)
    )
    try:
        states.clear()
        # The whole loop stalls, on purpose (as on a busy machine or in a long collection).
        time.sleep(0.3)  # noqa: ASYNC251
        before = originator.stats().packets_in
        await eventually(lambda: originator.stats().packets_in >= before + 20)
        assert target.counters.watchdog_timeouts == 0
        assert ConnectionState.LOST not in states
        assert originator.state is ConnectionState.CONNECTED
        assert len(target.connections()) == 1
    finally:
        await originator.stop()


async def test_a_silence_the_target_ends_right_after_the_first_look_keeps_the_connection(
    target: Target, robot_host: str, plc_host: str
) -> None:
    """As when the whole machine stops for longer than the timeout (a VM's host taking its
    CPUs): the target stopped too, and its next packet comes just after our first look at the
    silence. The verdict waits one RPI more, so that packet keeps the connection; a silence
    that goes on is still a timeout (test_service_robots and the e2e's emulator restart)."""
    states: list[ConnectionState] = []
    rpi_us = 200_000  # one RPI of grace: longer than any stall of this loop between two steps
    originator = await held(
        target, robot_host, plc_host, rpi_us, on_state=lambda state, reason: states.append(state)
    )
    try:
        states.clear()
        link = originator._link
        assert link is not None and link.last_payload is not None
        target.faults.t2o_silent = True
        await eventually(lambda: link.silence_seen_at is not None)
        # The target's packet after the stop, from its own address, next in both sequences.
        encap, cip = link.sequence.last_encap_seq, link.sequence.last_cip_seq
        assert encap is not None and cip is not None
        packet = io.encode_io(link.t2o_id, encap + 1, (cip + 1) & 0xFFFF, link.last_payload[0])
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.bind((robot_host, 0))
            sender.sendto(packet, (plc_host, ENIP_UDP_PORT))
        target.faults.t2o_silent = False
        before = originator.stats().packets_in
        await eventually(lambda: originator.stats().packets_in >= before + 3)
        assert ConnectionState.LOST not in states
        assert originator.state is ConnectionState.CONNECTED
    finally:
        await originator.stop()


# --------------------------------------------------------------------------- UDP endpoint


async def test_packets_read_later_keep_the_time_they_arrived(plc_host: str) -> None:
    """Read only at a tick, two packets 20 ms apart still show 20 ms between them: the time
    handed on is the kernel's receive time (the watchdog and O→T intervals rely on it)."""
    received: list[tuple[bytes, float]] = []
    endpoint = UdpEndpoint(
        plc_host,
        0,
        lambda data, addr, arrived: received.append((data, arrived)),
        receive_size=1501,
    )
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.sendto(b"first", (plc_host, endpoint.port))
            await asyncio.sleep(0.02)
            sender.sendto(b"second", (plc_host, endpoint.port))
        await asyncio.sleep(0.01)
        endpoint.drain()  # both at once, as a producer's tick reads them
    finally:
        endpoint.close()
    assert [data for data, _ in received] == [b"first", b"second"]
    assert received[1][1] - received[0][1] >= 0.015
