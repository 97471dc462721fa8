"""Bad input (issue 3, "Tests"): thousands of malformed encapsulation messages and UDP packets
thrown at the emulator and at the scanner while a connection runs. Nothing crashes or hangs,
each bad packet is counted, and the live connection carries on untouched."""

from __future__ import annotations

import asyncio
import random
import socket
import struct
from collections.abc import AsyncIterator

import pytest

from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.enip import cpf, encapsulation, io
from cobot_hmi.enip.encapsulation import Command
from cobot_hmi.scanner.originator import ConnectionState, Originator, OriginatorSettings
from waiting import eventually

COUNT = 2000


@pytest.fixture
async def live(robot_host: str, plc_host: str) -> AsyncIterator[tuple[Target, Originator]]:
    target = Target(TargetSettings(host=robot_host, tcp_port=0), StaticRobot())
    await target.start()
    states: list[ConnectionState] = []
    originator = Originator(
        OriginatorSettings(robot_host, target.tcp_port, local_host=plc_host, rpi_us=5_000),
        on_state=lambda state, reason: states.append(state),
    )
    await originator.start()
    try:
        assert await originator.wait_connected(5)
        yield target, originator
        assert originator.state is ConnectionState.CONNECTED
        assert ConnectionState.LOST not in states
        assert target.counters.watchdog_timeouts == 0
        assert len(target.connections()) == 1
    finally:
        await originator.stop()
        await target.stop()


def _bad_encapsulation(rng: random.Random) -> bytes:
    """One complete-but-wrong encapsulation message (its length field covers its data)."""
    kind = rng.randrange(6)
    context = rng.randbytes(8)
    if kind == 0:  # unknown command
        return encapsulation.encode(
            rng.choice([0x01, 0x55, 0x71, 0xFFFF]), rng.randbytes(rng.randrange(8))
        )
    if kind == 1:  # SendRRData without a session / with a bogus CPF
        items = rng.randbytes(rng.randrange(1, 40))
        return encapsulation.encode(Command.SEND_RR_DATA, b"\x00" * 6 + items, context=context)
    if kind == 2:  # RegisterSession with a wrong length or version
        return encapsulation.encode(Command.REGISTER_SESSION, rng.randbytes(rng.choice([0, 2, 6])))
    if kind == 3:  # CPF item whose length runs past the end
        body = b"\x00" * 6 + struct.pack("<HHH", 2, 0, 0) + struct.pack("<HH", 0xB2, 500) + b"\x0e"
        return encapsulation.encode(Command.SEND_RR_DATA, body)
    if kind == 4:  # bogus item types
        body = b"\x00" * 6 + cpf.encode_items([cpf.CpfItem(0x1234, b"x"), cpf.CpfItem(0xB2, b"")])
        return encapsulation.encode(Command.SEND_RR_DATA, body)
    return encapsulation.encode(Command.LIST_IDENTITY, rng.randbytes(rng.randrange(1, 30)))


async def test_malformed_encapsulation_at_the_emulator(
    live: tuple[Target, Originator], robot_host: str
) -> None:
    target, _ = live
    rng = random.Random(1)
    reader, writer = await asyncio.open_connection(robot_host, target.tcp_port)
    try:
        session_reply = encapsulation.encode(
            Command.REGISTER_SESSION, encapsulation.encode_register_session()
        )
        writer.write(session_reply)
        for _ in range(COUNT):
            writer.write(_bad_encapsulation(rng))
        writer.write(encapsulation.encode(Command.LIST_IDENTITY, context=b"the-end!"))
        await writer.drain()
        while True:  # every message gets its answer in order; the last one proves no hang
            head = await asyncio.wait_for(reader.readexactly(24), 10)
            header = encapsulation.decode_header(head)
            await reader.readexactly(header.length)
            if header.context == b"the-end!":
                break
    finally:
        writer.close()
        await writer.wait_closed()
    counted = (
        target.counters.encapsulation_malformed
        + target.counters.encapsulation_unsupported
        + target.counters.encapsulation_bad_session
    )
    assert counted >= COUNT * 0.95
    assert target.counters.internal_errors == 0
    # Truncated messages: a header cut short, a length promising more than ever comes.
    for junk in (b"\x65\x00\x04", encapsulation.encode(Command.LIST_IDENTITY)[:-1] + b"\xff" * 3):
        _r, w = await asyncio.open_connection(robot_host, target.tcp_port)
        w.write(junk)
        await w.drain()
        w.close()
        await w.wait_closed()


async def test_malformed_udp_at_both_ends(
    live: tuple[Target, Originator], robot_host: str, plc_host: str
) -> None:
    target, originator = live
    rng = random.Random(2)
    info = target.connections()[0]
    before = originator.stats()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
        udp.bind((plc_host, 0))  # the originator's own address, so only the packet is wrong
        for n in range(COUNT):
            kind = n % 5
            if kind == 0:
                packet = rng.randbytes(rng.randrange(0, 18))  # short
            elif kind == 1:
                packet = io.encode_io(rng.getrandbits(32) | 1, n, n, bytes(24), 1)  # wrong ID
            elif kind == 2:
                packet = rng.randbytes(1600)  # oversized
            elif kind == 3:  # stale: a sequence number far behind the live one
                packet = io.encode_io(
                    info.o2t_connection_id, (-10_000_000 - n) & 0xFFFFFFFF, n, bytes(24), 1
                )
            else:  # item list garbage with a valid prefix
                packet = io.encode_io(info.o2t_connection_id, n, n, b"")[:-1] + b"\x00\x00\x00"
            udp.sendto(packet, (robot_host, target.udp_port))
            t2o = bytes(packet)
            if kind == 3:
                t2o = io.encode_io(
                    info.t2o_connection_id, (-10_000_000 - n) & 0xFFFFFFFF, n, bytes(284)
                )
            udp.sendto(t2o, (plc_host, 2222))
            if n % 40 == 0:
                await asyncio.sleep(0.01)  # let both loops drain their sockets
    counters = target.counters

    def at_target() -> int:
        return counters.udp_malformed + counters.udp_unknown_connection + counters.udp_stale

    def at_scanner() -> int:
        now = originator.stats()
        return (
            now.malformed
            + now.foreign
            + now.stale
            - before.malformed
            - before.foreign
            - before.stale
        )

    # Both sides read their sockets and count (loopback may drop a few under load).
    await eventually(lambda: at_target() >= COUNT * 0.95 and at_scanner() >= COUNT * 0.95)
    after = originator.stats()
    assert after.gaps == before.gaps
    assert after.packets_in > before.packets_in
