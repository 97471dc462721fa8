"""The originator's class 1 port and connection start (issue 11, "Protocol layer"), on loopback:
N connections to N emulated targets on one UDP 2222 socket with independent statistics, T→O
accepted only from the target's address (a forged datagram from another loopback address is
counted as foreign and changes nothing), a granted packet interval outside its bounds refused
(a fake target answering the Forward Open with a crafted API), the target's first T→O accepted
even before the Forward Open reply is read, and the first O→T packet carrying the O→T assembly
read before the Forward Open.

The fake target is a small encapsulation server in this file: only what a target must do to
answer our session, our explicit read, our Forward Open and our Forward Close.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import socket
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from cobot_hmi.codec import CommandImage, Frame, decode_frame, encode_command, encode_frame
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.enip import cip, cpf, encapsulation, io
from cobot_hmi.enip.cip import MessageRouterResponse, Service
from cobot_hmi.enip.connection_manager import (
    ForwardCloseReply,
    ForwardOpenReply,
    ForwardOpenRequest,
    decode_forward_close,
    decode_forward_open,
)
from cobot_hmi.enip.cpf import CpfItem, ItemType
from cobot_hmi.enip.encapsulation import Command
from cobot_hmi.layout import ROBOT_STATES
from cobot_hmi.scanner.io_port import (
    BUSY_BATCH_S,
    HURRY_MIN_S,
    RECEIVE_BUFFER_BYTES,
    RING_SLOTS,
    IoPort,
    hurry_window_s,
)
from cobot_hmi.scanner.originator import ConnectionState, Originator, OriginatorSettings
from cobot_hmi.udp_endpoint import UdpEndpoint
from conftest import _next_host as next_host
from waiting import WAIT_DEADLINE_S, eventually

DEADLINE_S = WAIT_DEADLINE_S
EMERGENCY_STOP = next(s.value for s in ROBOT_STATES if s.name == "EMERGENCY_STOP")


# --------------------------------------------------------------------------- dispatch


class Recorder:
    """A T2OConsumer keeping what the port hands it."""

    def __init__(self) -> None:
        self.packets: list[bytes] = []
        self.foreign = 0
        self.malformed = 0
        self.batches = 0

    def t2o_packet(self, packet: io.IoPacket, arrived: float) -> None:
        self.packets.append(packet.payload)

    def t2o_foreign(self) -> None:
        self.foreign += 1

    def t2o_malformed(self) -> None:
        self.malformed += 1

    def t2o_batch_read(self, now: float) -> None:
        self.batches += 1


async def test_port_dispatches_by_connection_id_and_source(plc_host: str) -> None:
    """Each datagram goes where its connection ID and source say: to its connection from the
    connection's target; counted on that connection as foreign from anywhere else; an unknown
    ID or garbage from a target's address counted on that target's connection; from nowhere
    known, on the port."""
    first_host, second_host, stranger_host = next_host(), next_host(), next_host()
    port = IoPort(plc_host, 0)
    await port.open()
    first, second = Recorder(), Recorder()
    first_id, second_id = port.new_connection_id(), port.new_connection_id()
    assert first_id != second_id
    port.route(first_id, first_host, first, batch_s=0.0, silence_s=0.0)
    port.route(second_id, second_host, second, batch_s=0.0, silence_s=0.0)
    with pytest.raises(ValueError, match="routed already"):
        port.route(first_id, second_host, second, batch_s=0.0, silence_s=0.0)
    senders = {}
    try:
        for host in (first_host, second_host, stranger_host):
            sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sender.bind((host, 0))
            senders[host] = sender
        to = (plc_host, port.udp.port)
        senders[first_host].sendto(io.encode_io(first_id, 1, 1, b"one"), to)
        senders[second_host].sendto(io.encode_io(second_id, 1, 1, b"two"), to)
        senders[second_host].sendto(io.encode_io(first_id, 2, 2, b"forged"), to)
        senders[stranger_host].sendto(io.encode_io(first_id, 3, 3, b"forged"), to)
        senders[first_host].sendto(io.encode_io(0x1234, 1, 1, b"unknown"), to)
        senders[first_host].sendto(b"garbage", to)
        senders[stranger_host].sendto(io.encode_io(0x1234, 1, 1, b"unknown"), to)
        senders[stranger_host].sendto(b"garbage", to)
        await eventually(lambda: port.malformed == 1)
        await eventually(lambda: first.foreign == 3)
        assert second.foreign == 0
        assert first.packets == [b"one"] and second.packets == [b"two"]
        assert first.malformed == 1 and second.malformed == 0
        assert port.foreign == 1
        assert first.batches >= 1 and second.batches >= 1
        port.unroute(first_id)
        senders[first_host].sendto(io.encode_io(first_id, 4, 4, b"late"), to)
        await eventually(lambda: port.foreign == 2)
        assert first.packets == [b"one"]
    finally:
        for sender in senders.values():
            sender.close()
        port.close()


async def test_port_batch_shortens_as_connections_add_up(plc_host: str) -> None:
    """Eight connections at RPI 0.2 ms bring 40 000 packets a second: a 40 ms batch would fill
    1600 of the pump ring's 4096 slots, so the port wakes sooner (a quarter of the ring per
    batch, 25.6 ms); one connection asking for its T→O at once (an RPI of 10 ms or more) makes
    it wake per datagram while the port brings few packets, every ``BUSY_BATCH_S`` on a busy
    port."""
    port = IoPort(plc_host, 0)
    await port.open()
    try:
        consumers = [Recorder() for _ in range(9)]
        ids = [port.new_connection_id() for _ in consumers]
        port.route(
            ids[0], "127.0.0.1", consumers[0], batch_s=0.04, silence_s=0.0, packets_per_s=500
        )
        assert port.batch_s == pytest.approx(0.04)
        assert RING_SLOTS == 4096
        for connection_id, consumer in zip(ids[1:8], consumers[1:8], strict=True):
            port.route(
                connection_id,
                "127.0.0.1",
                consumer,
                batch_s=0.04,
                silence_s=0.032,
                packets_per_s=5000,
            )
        assert port.batch_s == pytest.approx(RING_SLOTS * 0.25 / (500 + 7 * 5000))
        port.route(
            ids[8], "127.0.0.1", consumers[8], batch_s=0.0, silence_s=0.16, packets_per_s=100
        )
        assert port.batch_s == pytest.approx(BUSY_BATCH_S), "a busy port"
        for connection_id in ids[:8]:
            port.unroute(connection_id)
        assert port.batch_s == 0.0, "100 packets/s, one connection at once: per datagram"
        port.unroute(ids[8])
        port.route(
            ids[0], "127.0.0.1", consumers[0], batch_s=0.04, silence_s=0.0, packets_per_s=500
        )
        assert port.batch_s == pytest.approx(0.04)
        assert RING_SLOTS == 4096
    finally:
        port.close()


# --------------------------------------------------------------------------- N connections


async def test_n_connections_to_n_targets_on_one_socket(plc_host: str) -> None:
    """Three emulated robots, one UDP 2222 socket of ours: each connection gets its own T→O
    (the three targets even choose the same O→T connection IDs), and a fault on one
    shows on that connection only: gaps on the second, a timeout on the third."""
    targets = [
        # The same seed: the three choose the same connection IDs.
        Target(TargetSettings(host=next_host(), tcp_port=0, seed=7), StaticRobot())
        for _ in range(3)
    ]
    for target in targets:
        await target.start()
    port = IoPort(plc_host)  # opened by the first originator that needs it
    originators: list[Originator] = []
    try:
        for target in targets:
            settings = OriginatorSettings(
                robot_host=target.settings.host,
                tcp_port=target.tcp_port,
                local_host=plc_host,
                rpi_us=5_000,
                timeout_multiplier=7,  # RPI × 512 = 2.6 s: load cannot time the others out
            )
            originator = Originator(settings, io_port=port)
            originators.append(originator)
            await originator.start()
        for originator in originators:
            assert await originator.wait_connected(DEADLINE_S)
        assert port.is_open and port.udp.port == 2222
        o2t_ids = {target.connections()[0].o2t_connection_id for target in targets}
        assert len(o2t_ids) == 1, "the emulators chose the same O→T ID: our tags keep them apart"
        assert {t.connections()[0].peer.split(":")[0] for t in targets} == {plc_host}

        first, second, third = originators
        await eventually(lambda: not port.hurried)  # the takeover's rebuild hurried it
        first.set_run(True)  # an O→T change: its confirmation is read per datagram
        assert port.hurried and port.batch_s == 0.0
        targets[1].faults.t2o_drop_percent = 30.0
        await eventually(lambda: second.stats().gaps >= 5)
        targets[1].faults.t2o_drop_percent = 0.0
        assert port.foreign == 0 and port.malformed == 0, "every datagram found its connection"
        targets[2].faults.t2o_silent = True
        await eventually(lambda: third.state is not ConnectionState.CONNECTED)
        assert third.reason is not None and "timed out" in third.reason
        for other in (first, second):
            assert other.state is ConnectionState.CONNECTED
        assert first.stats().gaps == 0
        for originator in originators:
            stats = originator.stats()
            assert stats.foreign == 0 and stats.malformed == 0
        # Every connection's O→T reached its own target.
        before = [t.connections()[0].packets_in for t in targets[:2]]
        await eventually(
            lambda: all(
                t.connections()[0].packets_in > n for t, n in zip(targets[:2], before, strict=True)
            )
        )
        assert all(o.packets_out > 0 for o in originators)
        targets[2].faults.t2o_silent = False
        assert await third.wait_connected(DEADLINE_S)
    finally:
        for originator in originators:
            await originator.stop()
        port.close()
        for target in targets:
            await target.stop()


# --------------------------------------------------------------------------- forged T→O


async def test_forged_t2o_from_another_address_is_foreign(
    target: Target, robot_host: str, plc_host: str
) -> None:
    """A datagram with the live T→O connection ID and a sequence number ahead, but from
    another loopback address than the target's, is counted as foreign and delivered nowhere:
    the frame it carries (emergency stop) never reaches ``on_frame``."""
    frames: list[Frame] = []
    settings = OriginatorSettings(
        robot_host=robot_host, tcp_port=target.tcp_port, local_host=plc_host, rpi_us=10_000
    )
    originator = Originator(
        settings, on_frame=lambda frame, _payload, at, seq: frames.append(frame)
    )
    await originator.start()
    try:
        assert await originator.wait_connected(DEADLINE_S)
        real = frames[-1]
        forged_frame = real._replace(robot_state=EMERGENCY_STOP)
        forged_data = encode_frame(forged_frame)
        assert decode_frame(forged_data).robot_state == EMERGENCY_STOP
        link = originator._link  # the live connection's numbers, as a sniffer would see them
        assert link is not None and link.sequence.last_encap_seq is not None
        t2o_id = link.t2o_id
        encap = link.sequence.last_encap_seq + 3
        cip_seq = (link.sequence.last_cip_seq or 0) + 3
        foreign_before = originator.stats().foreign
        gaps_before = originator.stats().gaps
        forger_host = next_host()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as forger:
            forger.bind((forger_host, 0))
            for n in range(5):
                packet = io.encode_io(t2o_id, encap + n, (cip_seq + n) & 0xFFFF, forged_data)
                forger.sendto(packet, (plc_host, 2222))
        await eventually(lambda: originator.stats().foreign >= foreign_before + 5)
        count = len(frames)
        await eventually(lambda: len(frames) >= count + 5)  # real T→O goes on
    finally:
        await originator.stop()
    assert all(frame.robot_state != EMERGENCY_STOP for frame in frames)
    assert originator.stats().gaps == gaps_before, "the forged numbers moved nothing"


# --------------------------------------------------------------------------- a fake target


@dataclasses.dataclass
class FakeTarget:
    """Answers a session, Get_Attribute_Single (the assembly), Forward Open (with the APIs it is
    told to grant) and Forward Close; records the O→T packets reaching its UDP 2222. With
    ``t2o_data`` it produces T→O every 10 ms on the originator's connection ID, the first
    packet *before* its Forward Open reply."""

    host: str
    o2t_api_us: int = 10_000
    t2o_api_us: int = 10_000
    assembly: bytes = b""
    t2o_data: bytes | None = None
    forward_opens: list[ForwardOpenRequest] = dataclasses.field(default_factory=list)
    forward_closes: int = 0
    o2t: list[bytes] = dataclasses.field(default_factory=list)
    tcp_port: int = 0
    _server: asyncio.Server | None = None
    _udp: UdpEndpoint | None = None
    _producers: list[asyncio.Task[None]] = dataclasses.field(default_factory=list)

    async def start(self) -> None:
        self._udp = UdpEndpoint(
            self.host, 2222, lambda data, addr, at: self.o2t.append(data), receive_size=1501
        )
        self._udp.watch(True)
        self._server = await asyncio.start_server(self._serve, self.host, 0)
        self.tcp_port = self._server.sockets[0].getsockname()[1]

    async def stop(self) -> None:
        for task in self._producers:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
        if self._udp is not None:
            self._udp.close()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        peer_host = writer.get_extra_info("peername")[0]
        try:
            while True:
                head = await reader.readexactly(encapsulation.HEADER_SIZE)
                header = encapsulation.decode_header(head)
                body = await reader.readexactly(header.length)
                if header.command == Command.REGISTER_SESSION:
                    writer.write(
                        encapsulation.encode(
                            header.command, body, session=7, context=header.context
                        )
                    )
                elif header.command == Command.SEND_RR_DATA:
                    _prefix, rest = encapsulation.decode_rr_prefix(body)
                    item = cpf.find_item(cpf.decode_items(rest), ItemType.UNCONNECTED_DATA)
                    assert item is not None
                    response = await self._answer(cip.decode_request(item.data), peer_host)
                    items = [
                        CpfItem(ItemType.NULL_ADDRESS, b""),
                        CpfItem(ItemType.UNCONNECTED_DATA, response.encode()),
                    ]
                    data = encapsulation.encode_rr_prefix(0) + cpf.encode_items(items)
                    writer.write(
                        encapsulation.encode(
                            header.command, data, session=7, context=header.context
                        )
                    )
                else:
                    break
                await writer.drain()
        except (asyncio.IncompleteReadError, ConnectionError):
            pass
        finally:
            writer.close()

    async def _answer(self, request: cip.MessageRouterRequest, peer: str) -> MessageRouterResponse:
        if request.service == Service.GET_ATTRIBUTE_SINGLE:
            return MessageRouterResponse(request.service, data=self.assembly)
        if request.service == Service.FORWARD_CLOSE:
            self.forward_closes += 1
            close = decode_forward_close(request.data)
            closed = ForwardCloseReply(
                close.connection_serial, close.vendor_id, close.originator_serial
            )
            return MessageRouterResponse(request.service, data=closed.encode())
        assert request.service == Service.FORWARD_OPEN
        fo = decode_forward_open(request.data, large=False)
        self.forward_opens.append(fo)
        if self.t2o_data is not None:
            assert self._udp is not None
            # The first T→O leaves before the reply (a fast target's usual order on a wire).
            self._udp.sendto(io.encode_io(fo.t2o_connection_id, 1, 1, self.t2o_data), (peer, 2222))
            await asyncio.sleep(0.05)
            self._producers.append(
                asyncio.get_running_loop().create_task(self._produce(fo.t2o_connection_id, peer))
            )
        reply = ForwardOpenReply(
            0x0BAD_CAFE,
            fo.t2o_connection_id,
            fo.connection_serial,
            fo.vendor_id,
            fo.originator_serial,
            self.o2t_api_us,
            self.t2o_api_us,
        )
        return MessageRouterResponse(request.service, data=reply.encode())

    async def _produce(self, t2o_id: int, peer: str) -> None:
        assert self._udp is not None and self.t2o_data is not None
        seq = 1
        while True:
            await asyncio.sleep(0.01)
            seq += 1
            data = seq.to_bytes(2, "little") + self.t2o_data[2:]
            self._udp.sendto(io.encode_io(t2o_id, seq, seq & 0xFFFF, data), (peer, 2222))


@pytest.fixture
async def fake(robot_host: str) -> AsyncIterator[FakeTarget]:
    target = FakeTarget(robot_host)
    await target.start()
    try:
        yield target
    finally:
        await target.stop()


def fake_settings(fake: FakeTarget, plc_host: str, **changes: object) -> OriginatorSettings:
    settings = OriginatorSettings(
        robot_host=fake.host,
        tcp_port=fake.tcp_port,
        local_host=plc_host,
        rpi_us=10_000,
        o2t_size=8,
        t2o_size=8,
        backoff_initial_s=0.5,
    )
    return dataclasses.replace(settings, **changes)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("o2t_api_us", "t2o_api_us", "words"),
    [(1, 10_000, "O→T packet interval of 1 µs"), (10_000, 0xFFFF_FFFF, "4294967295 µs")],
    ids=["1-us", "hours"],
)
async def test_granted_api_out_of_bounds_is_refused_and_closed(
    fake: FakeTarget, plc_host: str, o2t_api_us: int, t2o_api_us: int, words: str
) -> None:
    """A target granting 1 µs would have us send a datagram per microsecond; one granting
    hours would keep a dead connection looking alive. Both are refused in words, the
    connection the target opened is closed, and no O→T packet leaves."""
    fake.o2t_api_us, fake.t2o_api_us = o2t_api_us, t2o_api_us
    fake.t2o_data = bytes(8)
    states: list[tuple[ConnectionState, str | None]] = []
    originator = Originator(
        fake_settings(fake, plc_host), on_state=lambda state, why: states.append((state, why))
    )
    await originator.start()
    try:
        await eventually(lambda: originator.state is ConnectionState.REFUSED)
        reason = originator.reason
        assert reason is not None and words in reason and "5000–20000 µs" in reason
        await eventually(lambda: fake.forward_closes >= 1)
        assert ConnectionState.CONNECTED not in [state for state, _ in states]
    finally:
        await originator.stop()
    await asyncio.sleep(0.05)
    assert fake.o2t == [], "nothing sent on a refused grant"
    assert originator.packets_out == 0


async def test_configured_api_range_accepts_what_it_names(fake: FakeTarget, plc_host: str) -> None:
    fake.o2t_api_us = fake.t2o_api_us = 40_000
    fake.t2o_data = bytes(8)
    originator = Originator(fake_settings(fake, plc_host, api_bounds_us=(1_000, 50_000)))
    await originator.start()
    try:
        assert await originator.wait_connected(DEADLINE_S)
        assert originator.stats().rpi_us == 40_000
    finally:
        await originator.stop()


async def test_first_t2o_before_the_reply_is_ours_and_first_o2t_is_the_assembly(
    fake: FakeTarget, plc_host: str
) -> None:
    """The target's first T→O arrives before its Forward Open reply: it is on the connection
    ID we chose, so it is this connection's first data, not foreign. The first O→T packet
    carries the O→T assembly read before the Forward Open (idle), not zeros."""
    fake.assembly = bytes.fromhex("a5a5010203040506")
    fake.t2o_data = b"first!!!"
    data: list[bytes] = []
    originator = Originator(
        fake_settings(fake, plc_host), on_data=lambda payload, at, seq: data.append(payload)
    )
    await originator.start()
    try:
        assert await originator.wait_connected(DEADLINE_S)
        await eventually(lambda: len(fake.o2t) >= 3)
        stats = originator.stats()
    finally:
        await originator.stop()
    assert data[0] == b"first!!!"
    assert stats.foreign == 0 and stats.malformed == 0
    first = io.decode_io(fake.o2t[0])
    assert first.connection_id == 0x0BAD_CAFE and first.encap_seq == 1
    run, o2t_data = io.split_run_idle(first.payload)
    assert run is False
    assert o2t_data == fake.assembly
    for datagram in fake.o2t:  # every O→T packet: 8 data bytes, the size asked for
        packet = io.decode_io(datagram)
        assert packet.cip_seq is not None and len(packet.payload) == 4 + 8
    assert fake.forward_opens[0].o2t_params.size_bytes == 2 + 4 + 8
    assert fake.forward_opens[0].t2o_params.size_bytes == 2 + 8


async def test_first_o2t_of_the_robot_layout_is_the_assembly_read(
    fake: FakeTarget, plc_host: str
) -> None:
    """At the robot's sizes, too, the first O→T carries the command image read from the
    robot's O→T assembly (before any T→O frame could seed it)."""
    image = CommandImage(
        controlbox_do=(True,) + (False,) * 15,
        tool_do=(False, True, False, False, False, False),
        analog_output_type=(0, 1),
        analog_output=(1.5, 0.0),
        bit_input_registers=(True, False) * 32,
    )
    fake.assembly = encode_command(image)
    originator = Originator(fake_settings(fake, plc_host, o2t_size=20, t2o_size=284))
    await originator.start()
    try:
        await eventually(lambda: len(fake.o2t) >= 1)
    finally:
        await originator.stop()
    run, o2t_data = io.split_run_idle(io.decode_io(fake.o2t[0]).payload)
    assert run is False
    assert o2t_data == fake.assembly


async def test_a_hurried_busy_port_reads_per_datagram_for_its_window_then_batches_again(
    plc_host: str,
) -> None:
    """An O→T change's confirmation must not wait for a busy port's batch: ``hurry`` makes the
    port read per datagram for the window given (a second hurry within it extends it, never
    shortens it), then it batches again by itself."""
    port = IoPort(plc_host, 0)
    await port.open()
    try:
        for _ in range(16):  # a cell of 16 robots at RPI 10 ms: a busy port
            port.route(
                port.new_connection_id(),
                "127.0.0.1",
                Recorder(),
                batch_s=0.0,
                silence_s=0.16,
                packets_per_s=100,
            )
        assert port.batch_s == pytest.approx(BUSY_BATCH_S)
        port.hurry(0.3)
        assert port.hurried and port.batch_s == 0.0
        port.hurry(0.01)  # shorter than what is left: the window stays
        await asyncio.sleep(0.05)
        assert port.hurried and port.batch_s == 0.0
        await eventually(lambda: not port.hurried)
        assert port.batch_s == pytest.approx(BUSY_BATCH_S)
    finally:
        port.close()
    assert hurry_window_s(0.002) == pytest.approx(HURRY_MIN_S)
    assert hurry_window_s(0.1) == pytest.approx(0.8), "eight RPIs of a slow connection"


def _receive_buffer_cap_bytes() -> int:
    return int(Path("/proc/sys/net/core/rmem_max").read_text())


async def test_the_port_asks_the_kernel_for_a_receive_buffer_a_cell_needs(plc_host: str) -> None:
    """The socket's receive buffer is what the port asked for, within the system's cap (Linux
    reports twice the size asked: its bookkeeping), not the ~200 KiB default."""
    port = IoPort(plc_host, 0)
    await port.open()
    try:
        sock = port.udp._sock
        assert sock is not None
        granted = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        cap = _receive_buffer_cap_bytes()
        assert granted >= 2 * min(RECEIVE_BUFFER_BYTES, cap)
    finally:
        port.close()
