"""The originator's parts, each built alone (``scanner.connection``): the connection's status,
the O→T sender on a real O→T stream of a real UDP port, the T→O receiver fed by a real port from
a socket standing in for the target, and the lifecycle against the emulator's target with no
``Originator`` around it. What they do together is the class 1 tests' (test_class1_loopback,
test_class1_cycle, test_io_port).
"""

from __future__ import annotations

import asyncio
import socket
from collections.abc import AsyncIterator

import pytest

from cobot_hmi.codec import (
    O2T_SIZE,
    Frame,
    command_from_json,
    encode_command,
    encode_frame,
    zero_command,
    zero_frame,
)
from cobot_hmi.emulator.target import Target
from cobot_hmi.enip import io
from cobot_hmi.enip.encapsulation import ENIP_UDP_PORT
from cobot_hmi.scanner.connection.lifecycle import ConnectionLifecycle
from cobot_hmi.scanner.connection.link import Link
from cobot_hmi.scanner.connection.o2t_send import O2TSender
from cobot_hmi.scanner.connection.originator_settings import OriginatorSettings
from cobot_hmi.scanner.connection.state import (
    ConnectionState,
    ConnectionStatus,
    NotConnectedError,
    ReadOnlyError,
)
from cobot_hmi.scanner.connection.t2o_receive import T2OReceiver
from cobot_hmi.scanner.io_port import IoPort
from cobot_hmi.scanner.o2t_stream import O2TStream
from cobot_hmi.udp_endpoint import UdpEndpoint
from waiting import WAIT_DEADLINE_S, eventually

pytestmark = pytest.mark.both_pumps  # conftest: native and pure-Python pump
DEADLINE_S = WAIT_DEADLINE_S
RPI_US = 10_000


def link_to(target_host: str, addr: tuple[str, int] = ("0.0.0.0", ENIP_UDP_PORT)) -> Link:
    return Link(
        t2o_id=0x1000_0001,
        connection_serial=2,
        originator_serial=3,
        path=b"",
        target_host=target_host,
        o2t_api_us=RPI_US,
        t2o_api_us=RPI_US,
        o2t_id=0x2000_0002,
        o2t_addr=addr,
    )


@pytest.fixture
async def port(plc_host: str) -> AsyncIterator[IoPort]:
    """A real UDP port of the originator's side (the kernel picks its number)."""
    opened = IoPort(plc_host, 0)
    await opened.open()
    try:
        yield opened
    finally:
        opened.close()


# --------------------------------------------------------------------------- status


async def test_status_tells_each_change_once_and_survives_a_failing_callback() -> None:
    told: list[tuple[ConnectionState, str | None]] = []

    def on_state(state: ConnectionState, reason: str | None) -> None:
        told.append((state, reason))
        raise RuntimeError("a consumer's bug")

    status = ConnectionStatus(on_state)
    assert not await status.wait_connected(0.01)
    status.set(ConnectionState.CONNECTING, None)
    status.set(ConnectionState.CONNECTING, None)  # no change: not told again
    waiter = asyncio.ensure_future(status.wait_connected(DEADLINE_S))
    await asyncio.sleep(0)
    status.set(ConnectionState.CONNECTED, None)
    assert await waiter
    status.set(ConnectionState.LOST, "gone")
    assert told == [
        (ConnectionState.CONNECTING, None),
        (ConnectionState.CONNECTED, None),
        (ConnectionState.LOST, "gone"),
    ]
    assert (status.state, status.reason) == (ConnectionState.LOST, "gone")
    assert not await status.wait_connected(0.01)


# --------------------------------------------------------------------------- O→T sender


class Collector:
    """A UDP endpoint on the target's address collecting the O→T datagrams."""

    def __init__(self, host: str) -> None:
        self.packets: list[io.IoPacket] = []
        self.endpoint = UdpEndpoint(
            host,
            0,
            lambda data, _addr, _at: self.packets.append(io.decode_io(data)),
            receive_size=io.MAX_DATAGRAM + 1,
        )
        self.endpoint.watch(True)
        self.addr = (host, self.endpoint.port)

    def close(self) -> None:
        self.endpoint.close()


@pytest.fixture
async def collector(robot_host: str) -> AsyncIterator[Collector]:
    found = Collector(robot_host)
    try:
        yield found
    finally:
        found.close()


def carried(packet: io.IoPacket) -> tuple[bool, bytes]:
    return io.split_run_idle(packet.payload)


async def test_sender_alone_puts_its_image_and_run_on_a_real_stream(
    port: IoPort, collector: Collector, robot_host: str
) -> None:
    status = ConnectionStatus()
    sender = O2TSender(OriginatorSettings(robot_host, rpi_us=RPI_US), status)
    with pytest.raises(NotConnectedError):
        sender.set_run(True)
    with pytest.raises(ValueError, match="exceed the O→T size"):
        sender.set_o2t_data(bytes(O2T_SIZE + 1))
    link = link_to(robot_host, collector.addr)
    sender.attach(link, port)
    link.o2t = O2TStream(
        port.udp, port.new_tag(), collector.addr, 0.01, lambda: sender.packet(link)
    )
    link.o2t.start()
    await eventually(lambda: len(collector.packets) >= 2)
    assert collector.packets[0].connection_id == link.o2t_id
    assert carried(collector.packets[0]) == (False, encode_command(zero_command())), "idle"

    status.set(ConnectionState.CONNECTED, None)
    image = command_from_json({"controlbox_do": {"2": True}}, base=sender.command)
    sent = sender.set_command(image)
    sender.set_run(True)
    assert await sender.wait_sent(sent, DEADLINE_S)
    await eventually(lambda: carried(collector.packets[-1]) == (True, encode_command(image)))
    assert sender.run and sender.command == image

    sender.detach()
    out = sender.packets_out
    assert out >= len(collector.packets) >= sent
    await asyncio.sleep(0.05)
    assert sender.packets_out == out, "the closed stream's packets stay counted, none added"
    assert not await sender.wait_sent(out + 1, 0.05)


def test_sender_alone_takes_the_robots_outputs_over_once_and_keeps_the_read_registers(
    robot_host: str,
) -> None:
    sender = O2TSender(OriginatorSettings(robot_host), ConnectionStatus())
    registers = command_from_json({"bit_input_registers": {"5": True}}, base=zero_command())
    sender.adopt_assembly(encode_command(registers))  # what the explicit read returned
    assert sender.command == registers
    outputs = list(zero_frame().controlbox_do)
    outputs[0] = True
    frame: Frame = zero_frame()._replace(controlbox_do=tuple(outputs))
    sender.seed(frame)
    assert sender.command.controlbox_do == frame.controlbox_do
    assert sender.command.bit_input_registers == registers.bit_input_registers
    assert sender.o2t_data == encode_command(sender.command)

    given = OriginatorSettings(robot_host, o2t_data=b"\x01")
    kept = O2TSender(given, ConnectionStatus())
    kept.seed(frame)
    assert kept.o2t_data == b"\x01" + bytes(O2T_SIZE - 1), "given O→T data is never taken over"


def test_sender_alone_builds_an_input_only_heartbeat_and_refuses_outputs(robot_host: str) -> None:
    link = link_to(robot_host)
    for size, data in ((0, b""), (6, b"\x00" * 4)):
        settings = OriginatorSettings(robot_host, input_only=True, heartbeat_o2t_size=size)
        sender = O2TSender(settings, ConnectionStatus())
        packet = io.decode_io(sender.packet(link))
        assert (packet.connection_id, packet.payload) == (link.o2t_id, data)
        assert (packet.cip_seq is None) == (size == 0)
        with pytest.raises(ReadOnlyError):
            sender.set_run(True)
        with pytest.raises(ReadOnlyError):
            sender.set_o2t_data(b"")


# --------------------------------------------------------------------------- T→O receiver


class Target2O:
    """A socket on the target's address sending T→O packets of one connection."""

    def __init__(self, host: str, to: tuple[str, int], t2o_id: int) -> None:
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind((host, 0))
        self.to = to
        self.t2o_id = t2o_id

    def send(self, encap_seq: int, cip_seq: int, data: bytes) -> None:
        self.socket.sendto(io.encode_io(self.t2o_id, encap_seq, cip_seq, data), self.to)


async def test_receiver_alone_counts_decodes_seeds_once_and_hands_frames_on(
    port: IoPort, plc_host: str, robot_host: str
) -> None:
    seeded: list[Frame] = []
    handed: list[tuple[Frame, bytes, int]] = []
    settings = OriginatorSettings(robot_host, local_host=plc_host, rpi_us=RPI_US)
    receiver = T2OReceiver(
        settings,
        seed=seeded.append,
        on_frame=lambda frame, payload, _at, seq: handed.append((frame, payload, seq)),
    )
    loop = asyncio.get_running_loop()
    lost: asyncio.Future[str] = loop.create_future()
    first_frame: asyncio.Future[None] = loop.create_future()
    link = link_to(robot_host)
    receiver.attach(link, port, lost=lost, first_frame=first_frame)
    port.route(link.t2o_id, robot_host, receiver, batch_s=0.0, silence_s=0.0)
    target = Target2O(robot_host, (plc_host, port.udp.port), link.t2o_id)
    one = encode_frame(zero_frame()._replace(robot_state=1))
    two = encode_frame(zero_frame()._replace(robot_state=2))
    try:
        target.send(1, 1, one)
        await asyncio.wait_for(first_frame, DEADLINE_S)
        target.send(2, 1, one)  # the same CIP count: alive, no new data
        target.send(5, 4, two)  # two packets lost on the way
        target.send(3, 3, two)  # older than one received: stale
        target.send(6, 5, one[:-1])  # the wrong size
        await eventually(lambda: receiver.malformed == 1)
        intruder = Target2O(plc_host, (plc_host, port.udp.port), link.t2o_id)
        intruder.send(7, 6, one)  # this connection's ID from another address
        await eventually(lambda: receiver.foreign == 1)
        intruder.socket.close()
    finally:
        target.socket.close()
        port.unroute(link.t2o_id)
    assert [f.robot_state for f in seeded] == [1], "the takeover once, at the first frame"
    assert [(f.robot_state, p, s) for f, p, s in handed] == [(1, one, 1), (2, two, 5)]
    assert (receiver.packets_in, receiver.frames) == (3, 2)
    assert (receiver.duplicates, receiver.gaps, receiver.stale) == (1, 2, 1)
    assert receiver.latest is not None and receiver.latest[0].robot_state == 2
    receiver.detach()
    assert lost.cancelled() and receiver.link is None


async def test_receiver_alone_times_a_silent_connection_out_one_rpi_after_the_timeout(
    port: IoPort, robot_host: str
) -> None:
    settings = OriginatorSettings(robot_host, rpi_us=RPI_US, timeout_multiplier=0)
    receiver = T2OReceiver(settings, seed=lambda _frame: None)
    loop = asyncio.get_running_loop()
    lost: asyncio.Future[str] = loop.create_future()
    link = link_to(robot_host)
    receiver.attach(link, port, lost=lost, first_frame=loop.create_future())
    link.last_rx = loop.time()
    receiver.check_silence(link, loop.time(), 0.0)
    assert link.silence_seen_at is None, "within the timeout (RPI 10 ms × 4): nothing"
    await asyncio.sleep(0.05)
    receiver.check_silence(link, loop.time(), 0.0)
    assert link.silence_seen_at is not None and not lost.done(), "the first look only"
    reason = await asyncio.wait_for(lost, DEADLINE_S)  # the second look, one RPI later
    assert "no T→O for 40 ms" in reason and "connection timed out" in reason
    receiver.detach()


# --------------------------------------------------------------------------- lifecycle


def parts(
    settings: OriginatorSettings,
) -> tuple[ConnectionStatus, O2TSender, T2OReceiver, ConnectionLifecycle]:
    status = ConnectionStatus()
    sender = O2TSender(settings, status)
    receiver = T2OReceiver(settings, seed=sender.seed)
    return status, sender, receiver, ConnectionLifecycle(settings, status, sender, receiver)


async def test_lifecycle_alone_opens_supervises_and_closes_a_connection(
    target: Target, robot_host: str, plc_host: str
) -> None:
    settings = OriginatorSettings(
        robot_host, tcp_port=target.tcp_port, local_host=plc_host, rpi_us=RPI_US
    )
    status, sender, receiver, lifecycle = parts(settings)
    await lifecycle.start()
    try:
        assert await status.wait_connected(DEADLINE_S)
        assert lifecycle.owns_port and lifecycle.port is not None and lifecycle.port.is_open
        assert status.connected_since is not None and receiver.frames >= 1
        (info,) = target.connections()
        assert info.run is False, "every connection starts idle"
        sender.set_run(True)
        await eventually(lambda: target.connections()[0].run)
    finally:
        await lifecycle.stop()
    after: tuple[ConnectionState, float | None, bool] = (
        status.state,
        status.connected_since,
        sender.run,
    )
    assert after == (ConnectionState.IDLE, None, False)
    assert target.connections() == [], "closed with a Forward Close"
    assert lifecycle.port is not None and not lifecycle.port.is_open, "its own port, closed"


async def test_lifecycle_alone_reports_a_refusal_and_tries_again(
    target: Target, robot_host: str, plc_host: str
) -> None:
    settings = OriginatorSettings(
        robot_host,
        tcp_port=target.tcp_port,
        local_host=plc_host,
        rpi_us=RPI_US,
        o2t_size=18,
        backoff_initial_s=0.01,
    )
    status, _sender, _receiver, lifecycle = parts(settings)
    seen: list[ConnectionState] = []
    status.on_state = lambda state, _reason: seen.append(state)
    await lifecycle.start()
    try:
        await eventually(lambda: seen.count(ConnectionState.REFUSED) >= 2)
        assert status.reason is not None and "invalid O→T connection size" in status.reason
        assert ConnectionState.CONNECTED not in seen
    finally:
        await lifecycle.stop()
    assert status.state is ConnectionState.IDLE
