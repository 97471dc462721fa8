"""The cyclic pump through ``UdpEndpoint``, over real sockets on loopback, once with each
implementation (the C extension and the pure-Python pump, ``both_pumps``): the send queue (due
order, taking back), periodic streams (counters written and raised per packet, wrapping; a new
template from the next packet; where a stopped stream would have gone on), the receive ring
(kernel receive times, a datagram too long for its slot still seen as too long, a full ring
keeping the newest), batched wake-ups, and closing (a ``with`` block, an endpoint dropped
unclosed: its thread stops either way). Deadlines are generous: nothing here asserts a timing
figure.
"""

from __future__ import annotations

import asyncio
import gc
import os
import socket
import struct
import threading
from collections.abc import AsyncIterator

import pytest

from cobot_hmi.native import pure
from cobot_hmi.udp_endpoint import PERIODIC_MAX, RING_SLOTS, QueueFullError, UdpEndpoint
from waiting import WAIT_DEADLINE_S, eventually

pytestmark = pytest.mark.both_pumps  # conftest: native and pure-Python pump
DEADLINE_S = WAIT_DEADLINE_S
Received = list[tuple[bytes, tuple[str, int], float]]


@pytest.fixture
async def pair(plc_host: str, robot_host: str) -> AsyncIterator[tuple[UdpEndpoint, Received]]:
    """A sending endpoint and what a watching endpoint on another address receives."""
    received: Received = []
    receiver = UdpEndpoint(
        robot_host, 0, lambda d, a, t: received.append((d, a, t)), receive_size=64
    )
    receiver.watch(True)
    sender = UdpEndpoint(plc_host, 0, lambda *_: None, receive_size=64)
    sender.peer = (robot_host, receiver.port)  # type: ignore[attr-defined]
    try:
        yield sender, received
    finally:
        sender.close()
        receiver.close()


def pump_threads() -> int:
    """Pump threads alive in this process: the C ones by their kernel name, the Python ones by
    their thread name."""
    native = 0
    for task in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{task}/comm") as comm:
                native += comm.read().strip() == "cyclic-pump"
        except FileNotFoundError:  # ended meanwhile
            pass
    return native + sum(1 for t in threading.enumerate() if t.name == "cyclic-pump")


async def test_each_endpoint_runs_the_pump_asked_for_and_closing_stops_it(
    plc_host: str, pump_implementation: str
) -> None:
    before = pump_threads()
    with UdpEndpoint(plc_host, 0, lambda *_: None, receive_size=64) as endpoint:
        endpoint.watch(True)
        assert endpoint.implementation == pump_implementation
        assert pump_threads() == before + 1
    await eventually(lambda: pump_threads() == before)
    assert endpoint.counters()["sent"] == 0, "closed: neutral figures"
    endpoint.close()  # again: nothing


async def test_an_endpoint_closed_from_another_thread_leaves_the_loop_clean(plc_host: str) -> None:
    """The loop's reader goes through the loop's own thread; the pump stops at once."""
    loop = asyncio.get_running_loop()
    before = pump_threads()
    endpoint = UdpEndpoint(plc_host, 0, lambda *_: None, receive_size=64)
    endpoint.watch(True)
    notify_fd = endpoint._notify_fd
    await asyncio.to_thread(endpoint.close)
    await eventually(lambda: pump_threads() == before)
    await asyncio.sleep(0)  # the loop runs the reader's removal
    assert not loop.remove_reader(notify_fd), "the loop watches its descriptor no more"


async def test_an_endpoint_dropped_unclosed_stops_its_thread(plc_host: str) -> None:
    before = pump_threads()
    endpoint = UdpEndpoint(plc_host, 0, lambda *_: None, receive_size=64)
    endpoint.watch(True, silence_s=0.01)  # the loop watches it: still no strong reference
    port = endpoint.port
    assert pump_threads() == before + 1
    del endpoint
    gc.collect()
    await eventually(lambda: pump_threads() == before)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind((plc_host, port))  # and its socket is closed: the port is free again


async def test_queued_datagrams_leave_in_due_order_and_can_be_taken_back(
    pair: tuple[UdpEndpoint, Received],
) -> None:
    sender, received = pair
    peer = sender.peer  # type: ignore[attr-defined]
    loop = asyncio.get_running_loop()
    now = loop.time()
    # Due half a second on: all is queued (and x, y taken back) by a few calls without an
    # await between them, long before, however busy the machine.
    dues = ((b"c", 0.56), (b"a", 0.52), (b"b", 0.54), (b"x", 1.0), (b"y", 1.1))
    for label, delay_s in dues:
        sender.send_at(now + delay_s, label, peer, tag=7 if label in b"xy" else 1)
    assert sender.queued(7) == 2
    count, first_due = sender.cancel(7)
    assert count == 2
    assert first_due == pytest.approx(now + 1.0, abs=1e-6)
    await eventually(lambda: len(received) == 3)
    assert [d for d, _, _ in received] == [b"a", b"b", b"c"]
    await asyncio.sleep(now + 1.2 - loop.time())  # past the due times of x and y
    assert len(received) == 3, "what was taken back never left"
    assert sender.counters()["sent"] == 3


async def test_a_periodic_stream_raises_its_counters_per_packet_and_wraps(
    pair: tuple[UdpEndpoint, Received],
) -> None:
    sender, received = pair
    peer = sender.peer  # type: ignore[attr-defined]
    template = bytes(4) + b"data" + bytes(2)
    now = asyncio.get_running_loop().time()
    sender.send_every(3, now, 0.002, template, peer, (0, 0xFFFFFFFE), (8, 0xFFFE))
    await eventually(lambda: len(received) >= 4)
    sender.replace_periodic(3, bytes(4) + b"DATA" + bytes(2))
    await eventually(lambda: any(b"DATA" in d for d, _, _ in received))
    count_before = len(received)
    state = sender.stop_periodic(3)
    assert state is not None
    next32, next16, next_due = state
    await asyncio.sleep(0.02)
    packets = [d for d, _, _ in received]
    assert len(packets) <= count_before + 1, "stopped"
    counters = [struct.unpack_from("<I", p)[0] for p in packets]
    assert counters[:3] == [0xFFFFFFFE, 0xFFFFFFFF, 0]
    assert [struct.unpack_from("<H", p, 8)[0] for p in packets[:3]] == [0xFFFE, 0xFFFF, 0]
    assert counters == [(0xFFFFFFFE + i) & 0xFFFFFFFF for i in range(len(packets))]
    assert next32 == (counters[-1] + 1) & 0xFFFFFFFF
    assert next16 == (0xFFFE + len(packets)) & 0xFFFF
    assert next_due >= now + len(packets) * 0.002 - 1e-6
    first_new = next(i for i, p in enumerate(packets) if b"DATA" in p)
    assert all(b"DATA" in p for p in packets[first_new:]), "the new template from then on"
    assert sender.stop_periodic(3) is None


async def test_a_stream_template_must_hold_its_counters(
    pair: tuple[UdpEndpoint, Received],
) -> None:
    sender, _ = pair
    peer = sender.peer  # type: ignore[attr-defined]
    now = asyncio.get_running_loop().time()
    with pytest.raises(ValueError, match="does not fit"):
        sender.send_every(4, now, 0.01, b"abc", peer, (0, 1))
    sender.send_every(4, now + 10, 0.01, bytes(8), peer, (4, 1))
    with pytest.raises(ValueError, match="does not fit"):
        sender.replace_periodic(4, bytes(6))
    assert sender.replace_periodic(5, bytes(8)) is False, "no such stream"


async def test_one_pump_holds_a_stream_per_connection_of_a_cell(
    pair: tuple[UdpEndpoint, Received],
) -> None:
    """Every connection on one UDP 2222 socket has its own O→T stream: a pump holds
    ``PERIODIC_MAX`` of them (the same in both pumps), each sending, and refuses one more."""
    sender, received = pair
    peer = sender.peer  # type: ignore[attr-defined]
    assert PERIODIC_MAX == pure.PERIODIC_MAX >= 64
    now = asyncio.get_running_loop().time()
    for tag in range(PERIODIC_MAX):
        sender.send_every(100 + tag, now, 0.010, struct.pack("<IH", 0, tag), peer, (0, 0))
    with pytest.raises(QueueFullError, match="every periodic stream"):
        sender.send_every(999, now, 0.010, bytes(6), peer, (0, 0))
    await eventually(
        lambda: (
            {d[4:6] for d, _, _ in received}
            >= {struct.pack("<H", tag) for tag in range(PERIODIC_MAX)}
        )
    )
    for tag in range(PERIODIC_MAX):
        assert sender.stop_periodic(100 + tag) is not None


async def test_a_full_ring_keeps_the_newest_with_their_sources_and_times(
    plc_host: str,
) -> None:
    received: Received = []
    endpoint = UdpEndpoint(plc_host, 0, lambda d, a, t: received.append((d, a, t)), receive_size=64)
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.bind((plc_host, 0))
            sender.sendto(bytes(100), (plc_host, endpoint.port))  # longer than a slot
            for i in range(RING_SLOTS + 9):
                sender.sendto(struct.pack("<I", i), (plc_host, endpoint.port))
                if i % 32 == 31:
                    await asyncio.sleep(0.005)  # let the pump keep up with the socket
            source = sender.getsockname()
        await eventually(lambda: endpoint.counters()["received"] == RING_SLOTS + 10)
        endpoint.drain()
        overflows = endpoint.counters()["ring_overflows"]
    finally:
        endpoint.close()
    assert len(received) == RING_SLOTS, "a full ring drops the oldest"
    assert [struct.unpack("<I", d)[0] for d, _, _ in received] == list(range(9, RING_SLOTS + 9))
    assert all(addr == source for _, addr, _ in received)
    times = [t for _, _, t in received]
    assert times == sorted(times)
    assert overflows == 10


async def test_a_datagram_too_long_for_the_slot_is_seen_too_long(plc_host: str) -> None:
    received: Received = []
    endpoint = UdpEndpoint(plc_host, 0, lambda d, a, t: received.append((d, a, t)), receive_size=64)
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.sendto(bytes(100), (plc_host, endpoint.port))
        await eventually(lambda: endpoint.counters()["received"] == 1)
        endpoint.drain()
    finally:
        endpoint.close()
    assert len(received[0][0]) == 64, "cut to the slot, so longer than any accepted packet"


async def test_watching_in_batches_wakes_the_owner_once_per_batch(plc_host: str) -> None:
    received: Received = []
    batches: list[int] = []
    endpoint = UdpEndpoint(
        plc_host,
        0,
        lambda d, a, t: received.append((d, a, t)),
        receive_size=64,
        on_batch=lambda: batches.append(len(received)),
    )
    endpoint.watch(True, 0.05)
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            for i in range(20):
                sender.sendto(bytes([i]), (plc_host, endpoint.port))
                await asyncio.sleep(0.001)
        await eventually(lambda: len(received) == 20)
    finally:
        endpoint.close()
    assert [d[0] for d, _, _ in received] == list(range(20))
    # Once per batch window (50 ms from a batch's first datagram), counted on the kernel's
    # arrival times: a busy machine may spread the sends over more windows. A datagram that
    # lands while a batch is being handed on opens a window of its own, and on a loaded machine
    # (load 25) the handing on took long enough for two such: at most twice the windows, and
    # one, where a wake-up per datagram would be 20.
    windows, opened = 0, -1.0
    for _, _, arrived in received:
        if arrived >= opened + 0.05:
            windows, opened = windows + 1, arrived
    assert len(batches) <= 2 * windows + 1, (
        f"20 datagrams in {len(batches)} wake-ups, {windows} windows"
    )


async def test_silence_wakes_the_owner_once(plc_host: str) -> None:
    """Not watching, the owner still hears once that nothing has come for ``silence_s`` (a
    watchdog's cue), and not again until datagrams have come back and stopped again."""
    wakeups: list[int] = []
    received: Received = []
    endpoint = UdpEndpoint(
        plc_host,
        0,
        lambda d, a, t: received.append((d, a, t)),
        receive_size=64,
        on_batch=lambda: wakeups.append(len(received)),
    )
    endpoint.watch(False, silence_s=0.03)
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.sendto(b"one", (plc_host, endpoint.port))
            await eventually(lambda: wakeups == [1])
            await asyncio.sleep(0.1)
            assert wakeups == [1], "once per silence"
            sender.sendto(b"two", (plc_host, endpoint.port))
            await eventually(lambda: wakeups == [1, 2])
    finally:
        endpoint.close()
    assert [d for d, _, _ in received] == [b"one", b"two"]


def test_a_stalled_stream_catches_up_once_and_stays_on_its_grid() -> None:
    """After a stall of several periods the stream sends one packet for the missed ones (no
    burst) and its next ones stay on the ticks it started on, so streams sharing a phase keep
    sharing it (the C pump does the same in cyclic_pump_periodic.c)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        state = pure._State(sock.fileno(), 4, 64, 4, 64)
        try:
            period_ns = 10_000_000
            stream = pure._Periodic(
                1, 5 * period_ns, period_ns, sock.getsockname(), bytearray(8), 0, 4, 1, 1
            )
            state.periodics[1] = stream
            state.send_due(5 * period_ns)
            assert state.counters[0] == 1
            state.send_due(11 * period_ns + 3_000_000)  # stalled 5.3 periods
            assert state.counters[0] == 2, "one packet for the missed ones"
            assert stream.due_ns % period_ns == 0, "still on its grid"
            assert 10 * period_ns < stream.due_ns <= 11 * period_ns + 3_000_000
            state.send_due(stream.due_ns)
            assert state.counters[0] == 3 and stream.due_ns == 12 * period_ns
        finally:
            state.sock.close()
            os.close(state.kick_fd)
            os.close(state.notify_fd)
