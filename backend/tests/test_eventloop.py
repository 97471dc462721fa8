"""The product's event loop (``eventloop.precise_event_loop``): epoll, so file descriptors past
1023 work (``select()`` refuses them: the loop's thread would die), with a timerfd for
sub-millisecond timeouts whose expiry is never mistaken for an event. A class 1 exchange
through two endpoints (each pump once per implementation, ``both_pumps``) runs with more than
1100 descriptors open. Nothing here asserts a timing figure; the only time check is a lower
bound (a wait never ends before its timeout, or the loop would spin).
"""

from __future__ import annotations

import asyncio
import gc
import os
import resource
import selectors
import socket
import struct
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from cobot_hmi import eventloop
from cobot_hmi.eventloop import PreciseEpollSelector, precise_event_loop
from cobot_hmi.udp_endpoint import UdpEndpoint

DEADLINE_S = 5.0
OPEN_FDS = 1100


@contextmanager
def many_open_fds(count: int) -> Iterator[list[socket.socket]]:
    """``count`` more open descriptors (socket pairs), the soft fd limit raised to fit them."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    needed = count + 512
    if soft != resource.RLIM_INFINITY and soft < needed:
        if hard != resource.RLIM_INFINITY and hard < needed:
            pytest.skip(f"RLIMIT_NOFILE hard limit {hard} < {needed}")
        resource.setrlimit(resource.RLIMIT_NOFILE, (needed, hard))
    sockets: list[socket.socket] = []
    try:
        for _ in range(count // 2):
            sockets.extend(socket.socketpair())
        yield sockets
    finally:
        for s in sockets:
            s.close()
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))


async def exchange(plc_host: str, robot_host: str, high: socket.socket) -> None:
    """A periodic stream and a send from one endpoint to another, a reader on a descriptor
    past 1023, and a sub-millisecond timer, all on the running loop."""
    loop = asyncio.get_running_loop()
    received: list[bytes] = []
    batches: list[int] = []
    receiver = UdpEndpoint(
        robot_host,
        0,
        lambda data, _addr, _at: received.append(data),
        receive_size=64,
        on_batch=lambda: batches.append(len(received)),
    )
    sender = UdpEndpoint(plc_host, 0, lambda *_: None, receive_size=64)
    try:
        receiver.watch(True)
        peer = (robot_host, receiver.port)
        sender.send_every(1, loop.time(), 0.002, bytes(8), peer, (0, 0))
        assert sender.sendto(b"direct", peer)
        readable = asyncio.Event()
        loop.add_reader(high.fileno(), readable.set)
        try:
            fired = asyncio.Event()
            loop.call_later(0.0005, fired.set)
            await asyncio.wait_for(fired.wait(), DEADLINE_S)
            await asyncio.wait_for(readable.wait(), DEADLINE_S)
            end = loop.time() + DEADLINE_S
            while len(received) < 20:
                assert loop.time() < end, f"only {len(received)} datagrams arrived"
                await asyncio.sleep(0.01)
        finally:
            loop.remove_reader(high.fileno())
        sender.stop_periodic(1)
    finally:
        sender.close()
        receiver.close()
    assert b"direct" in received
    counts = [struct.unpack_from("<I", d)[0] for d in received if d != b"direct"]
    assert counts == list(range(len(counts))), "the stream's counter, in order, none lost"
    assert batches, "the pump woke the loop through its notification descriptor"


@pytest.mark.both_pumps  # conftest: native and pure-Python pump
def test_the_loop_and_the_endpoints_work_past_descriptor_1023(
    plc_host: str, robot_host: str
) -> None:
    with many_open_fds(OPEN_FDS) as sockets:
        high = sockets[-2]
        assert high.fileno() > 1100
        # What the product's loop used to be refuses such a descriptor: this test would catch it.
        with selectors.SelectSelector() as old:
            old.register(high, selectors.EVENT_READ)
            with pytest.raises(ValueError, match="out of range"):
                old.select(0)
        sockets[-1].send(b"x")  # `high` is readable
        with asyncio.Runner(loop_factory=precise_event_loop) as runner:
            runner.run(exchange(plc_host, robot_host, high))


def test_a_timer_expiry_is_no_event_and_a_wait_lasts_its_timeout() -> None:
    read_end, write_end = os.pipe()
    selector = PreciseEpollSelector()
    try:
        key = selector.register(read_end, selectors.EVENT_READ, "data")
        for timeout_s in (0.0003, 0.003):
            start_ns = time.monotonic_ns()
            assert selector.select(timeout_s) == []
            # A lower bound only (load makes a wait longer, never shorter); 1 µs for the
            # float-to-nanoseconds rounding of the timeout.
            waited_ns = time.monotonic_ns() - start_ns
            assert waited_ns >= timeout_s * 1e9 - 1_000, ("sooner than asked", waited_ns)
        assert selector.select(0) == [], "the expired timer was consumed"
        os.write(write_end, b"x")
        assert selector.select(None) == [(key, selectors.EVENT_READ)]
        assert selector.select(0.5) == [(key, selectors.EVENT_READ)]
    finally:
        selector.close()
        os.close(read_end)
        os.close(write_end)


def test_the_selector_keeps_the_selectors_contract() -> None:
    a, b = socket.socketpair()
    with a, b, PreciseEpollSelector() as selector:
        key = selector.register(a, selectors.EVENT_READ, "first")
        assert selector.get_key(a) is key
        assert selector.get_key(a.fileno()) is key
        with pytest.raises(KeyError):
            selector.register(a.fileno(), selectors.EVENT_WRITE)
        with pytest.raises(ValueError, match="invalid events"):
            selector.register(b, 0)
        key = selector.modify(a, selectors.EVENT_READ | selectors.EVENT_WRITE, "both")
        assert key.data == "both"
        assert selector.select(0) == [(key, selectors.EVENT_WRITE)]
        b.send(b"x")
        assert selector.select(0) == [(key, selectors.EVENT_READ | selectors.EVENT_WRITE)]
        assert list(selector.get_map()) == [a.fileno()]
        assert selector.unregister(a) == key
        with pytest.raises(KeyError):
            selector.unregister(a)
        assert selector.select(0) == []


def test_after_start_up_the_young_generation_is_collected_less_often() -> None:
    """``freeze_startup_heap`` freezes what exists and raises the youngest generation's
    threshold (a frame's objects die by reference counting before a collection looks at them),
    keeping the older generations' own."""
    before = gc.get_threshold()
    try:
        gc.set_threshold(700, 10, 10)
        eventloop.freeze_startup_heap()
        assert gc.get_threshold() == (eventloop.YOUNG_COLLECTION_THRESHOLD, 10, 10)
        assert gc.get_freeze_count() > 0
    finally:
        gc.set_threshold(*before)
