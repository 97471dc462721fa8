"""The pure EtherNet/IP packet code: golden bytes written from the CIP layouts
(docs/protocol.md), round trips, and every decoder raising only ``EnipError`` on garbage."""

from __future__ import annotations

import contextlib
from collections.abc import Callable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_hmi.enip import cip, connection_manager, cpf, encapsulation, epath, identity, io, status
from cobot_hmi.enip.connection_manager import (
    ConnectionType,
    ForwardCloseRequest,
    ForwardOpenReply,
    ForwardOpenRequest,
    NetworkParams,
    Priority,
)
from cobot_hmi.enip.errors import EnipError, PathError, TruncatedError

FORWARD_OPEN_GOLDEN = bytes.fromhex(
    "0a0e00000000443322113412feffefbeadde02000000102700001a48102700001e490104200424972c962c64"
)


def _forward_open(large: bool = False) -> ForwardOpenRequest:
    return ForwardOpenRequest(
        o2t_connection_id=0,
        t2o_connection_id=0x11223344,
        connection_serial=0x1234,
        vendor_id=0xFFFE,
        originator_serial=0xDEADBEEF,
        timeout_multiplier=2,
        o2t_rpi_us=10_000,
        o2t_params=NetworkParams(26),
        t2o_rpi_us=10_000,
        t2o_params=NetworkParams(286),
        path=epath.connection_path(151, 150, 100),
        large=large,
    )


def test_forward_open_golden_bytes() -> None:
    assert _forward_open().encode() == FORWARD_OPEN_GOLDEN
    decoded = connection_manager.decode_forward_open(FORWARD_OPEN_GOLDEN, large=False)
    assert decoded == _forward_open()
    assert decoded.o2t_params.connection_type is ConnectionType.POINT_TO_POINT
    assert decoded.o2t_params.priority is Priority.SCHEDULED
    path = epath.decode_connection_path(decoded.path)
    assert (path.class_id, path.config_instance, path.points) == (4, 151, (150, 100))


FORWARD_OPEN_16_BIT_GOLDEN = bytes.fromhex(
    # FORWARD_OPEN_GOLDEN with every segment of its connection path in the 16-bit form
    "0a0e00000000443322113412feffefbeadde02000000102700001a48102700001e4901"
    "08"  # path size: 8 words
    "2100040025009700"  # class 4, configuration instance 151
    "2d0096002d006400"  # connection points 150 (O→T) and 100 (T→O)
)


def test_a_sixteen_bit_connection_path_decodes_to_the_same_connection() -> None:
    decoded = connection_manager.decode_forward_open(FORWARD_OPEN_16_BIT_GOLDEN, large=False)
    assert decoded.path != _forward_open().path  # other bytes, the same meaning
    assert decoded.connection_path() == _forward_open().connection_path()
    assert decoded.connection_path().points == (150, 100)
    assert epath.connection_path(151, 150, 100, width=16) == decoded.path
    close = ForwardCloseRequest(1, 2, 3, decoded.path)
    assert connection_manager.decode_forward_close(close.encode()).connection_path() == (
        decoded.connection_path()
    )


def test_large_forward_open_round_trip() -> None:
    request = _forward_open(large=True)
    raw = request.encode()
    assert len(raw) == len(FORWARD_OPEN_GOLDEN) + 4
    assert connection_manager.decode_forward_open(raw, large=True) == request
    assert request.request().service == cip.Service.LARGE_FORWARD_OPEN


def test_network_parameters_bits() -> None:
    params = NetworkParams(286, ConnectionType.MULTICAST, Priority.HIGH, variable=True)
    assert params.encode16() == 1 << 13 | 1 << 10 | 1 << 9 | 286
    assert NetworkParams.decode16(params.encode16()) == params
    assert NetworkParams.decode32(params.encode32()) == params
    with pytest.raises(ValueError, match="Large Forward Open"):
        NetworkParams(600).encode16()


def test_forward_open_reply_and_failure_round_trip() -> None:
    reply = ForwardOpenReply(1, 2, 3, 4, 5, 10_000, 20_000)
    assert connection_manager.decode_forward_open_reply(reply.encode()) == reply
    failure = connection_manager.ConnectionFailureReply(3, 4, 5, 0)
    assert connection_manager.decode_failure_reply(failure.encode()) == failure
    response = cip.MessageRouterResponse(0x54, 0x01, (0x0127, 26), failure.encode())
    decoded = cip.decode_response(response.encode())
    assert decoded == response
    assert decoded.describe() == (
        "connection failure (0x01): invalid O→T connection size (0x0127); "
        "the target expected 26 bytes"
    )


def test_forward_close_round_trip() -> None:
    request = ForwardCloseRequest(1, 2, 3, epath.connection_path(151, 150, 100))
    assert connection_manager.decode_forward_close(request.encode()) == request
    reply = connection_manager.ForwardCloseReply(1, 2, 3)
    assert connection_manager.decode_forward_close_reply(reply.encode()) == reply


def test_unconnected_send_round_trip() -> None:
    inner = _forward_open().request().encode()
    wrapped = connection_manager.UnconnectedSend(inner + b"\x00", bytes((1, 0)))
    assert connection_manager.decode_unconnected_send(wrapped.encode()) == wrapped


def test_sockaddr_is_big_endian() -> None:
    raw = cpf.encode_sockaddr(cpf.Sockaddr("127.0.0.2", 2222))
    assert raw == bytes.fromhex("000208ae7f000002") + bytes(8)
    assert cpf.decode_sockaddr(raw) == cpf.Sockaddr("127.0.0.2", 2222)


def test_cpf_items_round_trip_and_errors() -> None:
    items = [cpf.CpfItem(0, b""), cpf.CpfItem(0xB2, b"\x0e\x03abc")]
    raw = cpf.encode_items(items)
    assert raw == bytes.fromhex("020000000000b2000500") + b"\x0e\x03abc"
    assert cpf.decode_items(raw) == items
    with pytest.raises(TruncatedError):
        cpf.decode_items(raw[:-1])
    with pytest.raises(EnipError, match="after the last"):
        cpf.decode_items(raw + b"x")


def test_encapsulation_header_golden() -> None:
    raw = encapsulation.encode(0x65, encapsulation.encode_register_session(), session=7)
    assert raw == bytes.fromhex("650004000700000000000000") + bytes(12) + b"\x01\x00\x00\x00"
    message = encapsulation.decode(raw)
    assert message.header.command == encapsulation.Command.REGISTER_SESSION
    assert encapsulation.decode_register_session(message.data).protocol_version == 1
    with pytest.raises(EnipError, match="length field"):
        encapsulation.decode(raw + b"\x00")


def test_message_router_request_round_trip() -> None:
    request = cip.MessageRouterRequest(0x0E, epath.request_path(4, 100, 3))
    raw = request.encode()
    assert raw == bytes.fromhex("0e03200424643003")
    assert cip.decode_request(raw) == request
    path = epath.decode_request_path(request.path)
    assert (path.class_id, path.instance, path.attribute) == (4, 100, 3)


def test_epath_sixteen_bit_and_key_and_data() -> None:
    key = epath.ElectronicKey(0xFFFE, 0x2B, 1, 1, 0)
    path = epath.connection_path(300, 301, 302, key=key, config_data=b"\x01\x02\x03")
    decoded = epath.decode_connection_path(path)
    assert decoded.key == key
    assert (decoded.config_instance, decoded.points) == (300, (301, 302))
    assert decoded.config_data == b"\x01\x02\x03\x00"
    with pytest.raises(PathError):
        epath.decode_connection_path(b"\x20\x04\x24")  # truncated
    with pytest.raises(PathError):
        epath.decode_connection_path(b"\xe0\x00")  # reserved segment type


def test_io_packet_golden_and_round_trip() -> None:
    raw = io.encode_io(0x01020304, 5, 6, b"\xaa\xbb", run_idle=1)
    assert raw == bytes.fromhex("0200028008000403020105000000b1000800060001000000aabb")
    packet = io.decode_io(raw)
    assert packet == io.IoPacket(0x01020304, 5, 6, b"\x01\x00\x00\x00\xaa\xbb")
    assert io.split_run_idle(packet.payload) == (True, b"\xaa\xbb")
    plain = io.decode_io(io.encode_io(9, 1, 2, b"xyz"))
    assert (plain.cip_seq, plain.payload) == (2, b"xyz")
    assert io.decode_io(io.encode_heartbeat(9, 3)).cip_seq is None


def test_sequence_comparisons_wrap() -> None:
    assert io.seq16_newer(0, 0xFFFF) == 1
    assert io.seq16_newer(0xFFFF, 0) == -1
    assert io.seq16_newer(5, 5) == 0
    assert io.seq32_newer(1, 0xFFFFFFFF) == 2


def test_identity_round_trip() -> None:
    info = identity.IdentityInfo(0xFFFE, 0x2B, 1, 2, 3, 0x0030, 0x12345678, "Robot")
    assert identity.decode_attributes_all(info.encode_attributes_all()) == info
    item = info.encode_list_identity_item(cpf.Sockaddr("127.0.0.2", 44818))
    decoded, address = identity.decode_list_identity_item(item)
    assert decoded == info
    assert address == cpf.Sockaddr("127.0.0.2", 44818)
    assert info.encode_attribute(7) == b"\x05Robot"


def test_status_words() -> None:
    assert "ownership conflict" in status.describe(1, (0x0106,))
    assert "RPI not supported" in status.describe(1, (0x0111,))
    assert status.describe(0x08) == "service not supported (0x08)"
    assert status.expected_size((0x0128, 286)) == 286
    for code in (
        0x0100,
        0x0106,
        0x0109,
        0x0111,
        0x0113,
        0x0114,
        0x0117,
        0x0127,
        0x0128,
        0x0203,
        0x0315,
    ):
        assert not status.extended_words(code).startswith("unknown")


DECODERS: list[Callable[[bytes], object]] = [
    encapsulation.decode,
    encapsulation.decode_register_session,
    encapsulation.decode_rr_prefix,
    cpf.decode_items,
    cpf.decode_sockaddr,
    epath.decode_segments,
    epath.decode_request_path,
    epath.decode_connection_path,
    cip.decode_request,
    cip.decode_response,
    lambda raw: connection_manager.decode_forward_open(raw, large=False),
    lambda raw: connection_manager.decode_forward_open(raw, large=True),
    connection_manager.decode_forward_open_reply,
    connection_manager.decode_failure_reply,
    connection_manager.decode_forward_close,
    connection_manager.decode_forward_close_reply,
    connection_manager.decode_unconnected_send,
    io.decode_io,
    identity.decode_attributes_all,
    identity.decode_list_identity_item,
]


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=96))
def test_decoders_raise_only_enip_errors(raw: bytes) -> None:
    for decoder in DECODERS:
        with contextlib.suppress(EnipError):
            decoder(raw)


@settings(max_examples=200, deadline=None)
@given(st.data())
def test_truncations_of_valid_packets_raise_enip_errors(data: st.DataObject) -> None:
    valid: list[tuple[Callable[[bytes], object], bytes]] = [
        (lambda raw: connection_manager.decode_forward_open(raw, large=False), FORWARD_OPEN_GOLDEN),
        (io.decode_io, io.encode_io(1, 2, 3, bytes(20), 1)),
        (cip.decode_response, cip.MessageRouterResponse(0x54, 1, (0x127, 26)).encode()),
    ]
    for decoder, raw in valid:
        cut = data.draw(st.integers(0, len(raw) - 1))
        flip = data.draw(st.integers(0, len(raw) - 1))
        for candidate in (raw[:cut], raw[:flip] + bytes((raw[flip] ^ 0xFF,)) + raw[flip + 1 :]):
            with contextlib.suppress(EnipError):
                decoder(candidate)
