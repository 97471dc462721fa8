"""Forward Opens whose paths use 16- and 32-bit segments, and malformed paths, against the real
emulator on loopback; the O→T receive rules (``enip.sequence``) over real UDP.

Every byte the test sends is built here from the layouts of CIP Vol 2 §2-3 (encapsulation),
§2-6 (Common Packet Format), Vol 1 §3-5.4 (Forward Open, Large Forward Open, Forward Close) and
Vol 1 Appendix C (segments), as docs/protocol.md gives them; not by ``cobot_hmi.enip``. A PLC
that writes ``21 00 06 00 25 00 01 00`` for the Connection Manager (EIPScanner's default, and
what many PLCs send for instance numbers above 255) must get the same connection as ours.
"""

from __future__ import annotations

import asyncio
import socket
import struct
from collections.abc import AsyncIterator
from dataclasses import dataclass

import pytest

from cobot_hmi.codec import command_from_json, encode_command
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.scanner.originator import ConnectionState
from emulator_harness import running_emulator
from waiting import WAIT_DEADLINE_S, eventually

DEADLINE_S = WAIT_DEADLINE_S

ENCAP: struct.Struct = struct.Struct("<HHII8sI")  # command, length, session, status, context, opts
REGISTER_SESSION, SEND_RR_DATA = 0x65, 0x6F
FORWARD_OPEN, LARGE_FORWARD_OPEN, FORWARD_CLOSE, GET_ATTRIBUTE_SINGLE = 0x54, 0x5B, 0x4E, 0x0E
POINT_TO_POINT_SCHEDULED_16 = 2 << 13 | 2 << 10
POINT_TO_POINT_SCHEDULED_32 = 2 << 29 | 2 << 26


def logical(kind: int, value: int, width: int) -> bytes:
    """A padded logical segment (CIP Vol 1 C-1.4.2): class 0, instance 1, point 3, attr 4."""
    head = 0x20 | kind << 2
    if width == 8:
        return bytes((head, value))
    if width == 16:
        return bytes((head | 1, 0)) + struct.pack("<H", value)
    return bytes((head | 2, 0)) + struct.pack("<I", value)


def cm_path(width: int) -> bytes:
    return logical(0, 0x06, width) + logical(1, 1, width)


def assembly_path(width: int, config: int = 151, o2t: int = 150, t2o: int = 100) -> bytes:
    return (
        logical(0, 0x04, width)
        + logical(1, config, width)
        + logical(3, o2t, width)
        + (logical(3, t2o, width))
    )


@dataclass
class Reply:
    service: int
    general: int
    additional: tuple[int, ...]
    data: bytes


class RawClient:
    """An encapsulation session over TCP, every byte packed here."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader = reader
        self.writer = writer
        self.session = 0

    @classmethod
    async def connect(cls, target: Target, local_host: str) -> RawClient:
        reader, writer = await asyncio.open_connection(
            target.settings.host, target.tcp_port, local_addr=(local_host, 0)
        )
        client = cls(reader, writer)
        command, _, session, status, _ = await client._transact(
            REGISTER_SESSION, struct.pack("<HH", 1, 0)
        )
        assert (command, status) == (REGISTER_SESSION, 0)
        client.session = session
        return client

    async def close(self) -> None:
        self.writer.close()
        await self.writer.wait_closed()

    async def _transact(self, command: int, data: bytes) -> tuple[int, int, int, int, bytes]:
        header = ENCAP.pack(command, len(data), self.session, 0, b"pathtest", 0)
        self.writer.write(header + data)
        await self.writer.drain()
        head = await asyncio.wait_for(self.reader.readexactly(ENCAP.size), DEADLINE_S)
        reply_command, length, session, status, context, _ = ENCAP.unpack(head)
        assert context == b"pathtest"
        body = await asyncio.wait_for(self.reader.readexactly(length), DEADLINE_S)
        return reply_command, length, session, status, body

    async def request(self, service: int, path: bytes, data: bytes = b"") -> Reply:
        """One Message Router request in a SendRRData: Null Address + Unconnected Data."""
        message = bytes((service, len(path) // 2)) + path + data
        items = struct.pack("<HHH", 2, 0x0000, 0) + struct.pack("<HH", 0x00B2, len(message))
        body = struct.pack("<IH", 0, 0) + items + message
        command, _, _, status, reply = await self._transact(SEND_RR_DATA, body)
        assert (command, status) == (SEND_RR_DATA, 0)
        (count,) = struct.unpack_from("<H", reply, 6)
        offset = 8
        for _ in range(count):
            item_type, length = struct.unpack_from("<HH", reply, offset)
            offset += 4
            if item_type == 0x00B2:
                mr = reply[offset : offset + length]
                reply_service, _, general, words = struct.unpack_from("<BBBB", mr)
                additional = struct.unpack_from(f"<{words}H", mr, 4)
                return Reply(reply_service, general, additional, mr[4 + 2 * words :])
            offset += length
        raise AssertionError("no Unconnected Data item in the reply")


def forward_open_data(
    path: bytes, *, large: bool, serial: int, t2o_id: int, rpi_us: int = 100_000
) -> bytes:
    """Forward Open (or Large) service data, multiplier 7: a watchdog of 512 RPIs."""
    head = struct.pack("<BBIIHHIB3x", 0x0A, 0x0E, 0, t2o_id, serial, 0x1234, 0xC0FFEE, 7)
    if large:
        tail = struct.pack(
            "<IIIIBB",
            rpi_us,
            POINT_TO_POINT_SCHEDULED_32 | 26,
            rpi_us,
            POINT_TO_POINT_SCHEDULED_32 | 286,
            0x01,
            len(path) // 2,
        )
    else:
        tail = struct.pack(
            "<IHIHBB",
            rpi_us,
            POINT_TO_POINT_SCHEDULED_16 | 26,
            rpi_us,
            POINT_TO_POINT_SCHEDULED_16 | 286,
            0x01,
            len(path) // 2,
        )
    return head + tail + path


def forward_close_data(path: bytes, serial: int) -> bytes:
    return struct.pack("<BBHHIBx", 0x0A, 0x0E, serial, 0x1234, 0xC0FFEE, len(path) // 2) + path


@pytest.fixture
async def udp(plc_host: str) -> AsyncIterator[socket.socket]:
    """The PLC's class 1 socket: T→O comes to port 2222 of the address it opened from."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((plc_host, 2222))
    sock.setblocking(False)
    try:
        yield sock
    finally:
        sock.close()


async def receive_t2o(sock: socket.socket, t2o_id: int) -> tuple[int, int]:
    """The next T→O datagram for ``t2o_id``: its (encapsulation sequence, CIP sequence)."""
    loop = asyncio.get_running_loop()
    while True:
        data = await asyncio.wait_for(loop.sock_recv(sock, 2048), DEADLINE_S)
        count, addr_type, addr_len, conn_id, seq, data_type, length, cip_seq = struct.unpack_from(
            "<HHHIIHHH", data
        )
        assert (count, addr_type, addr_len, data_type) == (2, 0x8002, 8, 0x00B1)
        assert length == 2 + 284 == len(data) - 18
        if conn_id == t2o_id:
            return seq, cip_seq


@pytest.mark.parametrize(
    ("width", "large"), [(16, False), (32, True), (16, True), (8, False)], ids=str
)
async def test_forward_open_in_every_width_opens_the_same_connection(
    target: Target, plc_host: str, udp: socket.socket, width: int, large: bool
) -> None:
    client = await RawClient.connect(target, plc_host)
    try:
        service = LARGE_FORWARD_OPEN if large else FORWARD_OPEN
        data = forward_open_data(assembly_path(width), large=large, serial=0x0101, t2o_id=0xABCD)
        reply = await client.request(service, cm_path(width), data)
        assert (reply.service, reply.general, reply.additional) == (service | 0x80, 0, ())
        o2t_id, t2o_id, serial, vendor, originator = struct.unpack_from("<IIHHI", reply.data)
        assert (t2o_id, serial, vendor, originator) == (0xABCD, 0x0101, 0x1234, 0xC0FFEE)
        (info,) = target.connections()
        assert (info.o2t_connection_id, info.kind) == (o2t_id, "owner")
        await receive_t2o(udp, t2o_id)  # the connection produces

        close = await client.request(
            FORWARD_CLOSE, cm_path(width), forward_close_data(assembly_path(width), 0x0101)
        )
        assert (close.service, close.general) == (FORWARD_CLOSE | 0x80, 0)
        assert target.connections() == []
        assert target.counters.forward_open_refusals == 0
        assert target.forward_open_refusals() == []
    finally:
        await client.close()


def o2t_packet(o2t_id: int, encap_seq: int, cip_seq: int, command: bytes) -> bytes:
    """An O→T datagram: Sequenced Address, Connected Data with count, run header, data."""
    return struct.pack(
        "<HHHIIHHHI", 2, 0x8002, 8, o2t_id, encap_seq, 0x00B1, 2 + 4 + len(command), cip_seq, 1
    ) + (command)


async def test_o2t_sequence_rules_at_the_target(
    target: Target, robot: StaticRobot, plc_host: str, udp: socket.socket
) -> None:
    """New data applied, a backwards CIP count and an old encapsulation number discarded as
    stale, a repeated count kept alive but not applied, a jump counted as a gap: the receive
    rules of ``enip.sequence``, the same the originator applies to T→O."""
    client = await RawClient.connect(target, plc_host)
    try:
        data = forward_open_data(assembly_path(16), large=False, serial=7, t2o_id=0x5151)
        reply = await client.request(FORWARD_OPEN, cm_path(16), data)
        assert reply.general == 0
        (o2t_id,) = struct.unpack_from("<I", reply.data)
        to = (target.settings.host, target.udp_port)
        first = command_from_json({"controlbox_do": {"1": True}})
        second = command_from_json({"controlbox_do": {"2": True}})

        def info_of() -> tuple[int, int, int]:
            (info,) = target.connections()
            return info.packets_in, info.o2t_duplicates, info.o2t_gaps

        udp.sendto(o2t_packet(o2t_id, 1, 10, encode_command(first)), to)
        await eventually(lambda: robot.command_image() == first)

        udp.sendto(o2t_packet(o2t_id, 2, 9, encode_command(second)), to)  # CIP count back
        await eventually(lambda: target.counters.udp_stale == 1)
        assert robot.command_image() == first, "a backwards count must not be applied"

        udp.sendto(o2t_packet(o2t_id, 3, 10, encode_command(second)), to)  # same count
        await eventually(lambda: info_of()[1] == 1)
        assert robot.command_image() == first, "a duplicate carries no new data"

        udp.sendto(o2t_packet(o2t_id, 4, 14, encode_command(second)), to)  # 3 lost
        await eventually(lambda: robot.command_image() == second)
        assert info_of() == (3, 1, 3)

        udp.sendto(o2t_packet(o2t_id, 4, 15, encode_command(first)), to)  # number not newer
        await eventually(lambda: target.counters.udp_stale == 2)
        assert robot.command_image() == second
        assert info_of() == (3, 1, 3)
    finally:
        await client.close()


MALFORMED_CONNECTION_PATHS = [
    "210006",  # cut inside a 16-bit class segment (padded to a word below)
    "2100040025009700",  # no connection points
    "2100040025009700230096002d006400",  # a reserved logical format
    "3405feff2b00f50302000c00200424972c962c64",  # electronic key format 5
    "200424972c962c64400001",  # a network segment after the points
    "e0000000",  # a reserved segment type
    "91036162630020042497",  # a symbolic segment
]


async def test_malformed_paths_get_their_statuses_and_the_session_stays_open(
    target: Target, plc_host: str, udp: socket.socket
) -> None:
    client = await RawClient.connect(target, plc_host)
    try:
        for serial, hex_path in enumerate(MALFORMED_CONNECTION_PATHS, start=100):
            path = bytes.fromhex(hex_path)
            path += b"\x00" * (len(path) % 2)
            data = forward_open_data(path, large=False, serial=serial, t2o_id=serial)
            reply = await client.request(FORWARD_OPEN, cm_path(16), data)
            assert (reply.general, reply.additional) == (0x01, (0x0315,)), hex_path
            # The failure reply names the connection (serial, vendor, originator serial).
            assert struct.unpack_from("<HHI", reply.data) == (serial, 0x1234, 0xC0FFEE)

        # A request path that does not decode: path segment error, for any service.
        bad_request_path = bytes.fromhex("21000600230001000000")
        good = forward_open_data(assembly_path(16), large=False, serial=1, t2o_id=1)
        reply = await client.request(FORWARD_OPEN, bad_request_path, good)
        assert (reply.general, reply.additional) == (0x04, ())
        reply = await client.request(GET_ATTRIBUTE_SINGLE, bytes.fromhex("2001240130"))
        assert reply.general == 0x04

        # The same session still works, in any width.
        name = await client.request(
            GET_ATTRIBUTE_SINGLE, logical(0, 1, 16) + logical(1, 1, 32) + logical(4, 7, 16)
        )
        assert name.general == 0 and name.data == target.identity.encode_attribute(7)
        reply = await client.request(FORWARD_OPEN, cm_path(16), good)
        assert reply.general == 0

        counts = {
            (r.general_status, r.extended_status): r.count for r in target.forward_open_refusals()
        }
        assert counts == {(0x01, 0x0315): len(MALFORMED_CONNECTION_PATHS), (0x04, None): 1}
        assert target.counters.forward_open_refusals == len(MALFORMED_CONNECTION_PATHS) + 1
    finally:
        await client.close()


async def test_refusals_are_counted_in_the_control_api_status(
    robot_host: str, plc_host: str
) -> None:
    async with running_emulator(robot_host, plc_host) as emulator:
        await emulator.post("/faults", {"refuse_next_forward_open": "0x0113"})
        originator = await emulator.connect()
        assert await originator.wait_connected(10.0)  # refused once, then connected
        assert any(state is ConnectionState.REFUSED for state, _ in emulator.connection_states)
        status = (await emulator.api.get("/status")).json()
        (refusal,) = status["forward_open_refusals"]
        assert refusal["general_status"] == 0x01
        assert refusal["extended_status"] == 0x0113
        assert refusal["count"] == 1
        assert "out of connections" in refusal["meaning"]
        assert status["target_counters"]["forward_open_refusals"] == 1


UNCONNECTED_SEND = 0x52


def unconnected_send_data(message: bytes, route: bytes) -> bytes:
    """Unconnected Send service data: tick, ticks, message size, message (padded), route path
    size in words, reserved, route path (CIP Vol 1 §3-5.5)."""
    pad = b"\x00" * (len(message) % 2)
    return (
        struct.pack("<BBH", 0x0A, 0x0E, len(message))
        + message
        + pad
        + bytes((len(route) // 2, 0))
        + route
    )


async def test_a_forward_open_inside_an_unconnected_send_in_16_bits(
    target: Target, plc_host: str, udp: socket.socket
) -> None:
    """The route (port 1, slot 0) ends here; a route that is not port segments is refused."""
    client = await RawClient.connect(target, plc_host)
    try:
        fo = forward_open_data(assembly_path(16), large=False, serial=9, t2o_id=0x99)
        message = bytes((FORWARD_OPEN, 4)) + cm_path(16) + fo
        bad = await client.request(
            UNCONNECTED_SEND, cm_path(16), unconnected_send_data(message, logical(1, 1, 8))
        )
        assert (bad.service, bad.general, bad.additional) == (UNCONNECTED_SEND | 0x80, 1, (0x0315,))
        assert target.connections() == []
        reply = await client.request(
            UNCONNECTED_SEND, cm_path(16), unconnected_send_data(message, bytes.fromhex("0100"))
        )
        # The embedded request's reply stands for the Unconnected Send's.
        assert (reply.service, reply.general) == (FORWARD_OPEN | 0x80, 0)
        (info,) = target.connections()
        assert info.t2o_connection_id == 0x99
        counts = {
            (r.general_status, r.extended_status): r.count for r in target.forward_open_refusals()
        }
        assert counts == {(0x01, 0x0315): 1}
    finally:
        await client.close()
