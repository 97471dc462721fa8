"""EPATHs (``enip.epath``), by property: any valid path, its segments in any width (8, 16 or
32 bits), with or without route, key and configuration data, decodes to the same class,
instance, attribute and connection points; malformed paths raise ``PathError`` and nothing else;
the target answers them with 0x04 (explicit) or 0x01 / 0x0315 (Forward Open) and never raises.

The paths are built here from the segment layout of CIP Vol 1 Appendix C (docs/protocol.md
"Paths"), not by the encoder under test.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings, default_identity
from cobot_hmi.enip import cip, epath
from cobot_hmi.enip.cip import MessageRouterRequest, Service
from cobot_hmi.enip.connection_manager import ForwardOpenRequest, NetworkParams
from cobot_hmi.enip.errors import PathError
from cobot_hmi.enip.status import ExtendedStatus, GeneralStatus

CLASS, INSTANCE, MEMBER, POINT, ATTRIBUTE = 0, 1, 2, 3, 4
MAX = {8: 0xFF, 16: 0xFFFF, 32: 0xFFFF_FFFF}


def logical(kind: int, value: int, width: int) -> bytes:
    """A logical segment as CIP Vol 1 C-1.4.2 lays it out (padded: a pad byte before 16- and
    32-bit values)."""
    head = 0x20 | kind << 2
    if width == 8:
        return bytes((head, value))
    if width == 16:
        return bytes((head | 1, 0)) + struct.pack("<H", value)
    return bytes((head | 2, 0)) + struct.pack("<I", value)


def port(number: int, link: bytes) -> bytes:
    """A port segment (CIP Vol 1 C-1.4.1), padded to a whole word."""
    extended = len(link) > 1
    out = bytes(((0x10 if extended else 0) | min(number, 15),))
    if extended:
        out += bytes((len(link),))
    if number >= 15:
        out += struct.pack("<H", number)
    out += link
    return out + b"\x00" * (len(out) % 2)


widths = st.sampled_from([8, 16, 32])


@st.composite
def value_in(draw: st.DrawFn, width: int, low: int = 0) -> int:
    return draw(st.integers(low, MAX[width]))


@st.composite
def logical_segments(draw: st.DrawFn, kind: int, low: int = 0) -> tuple[int, bytes, int]:
    """(value, bytes, size) of one logical segment in a width drawn for it."""
    width = draw(widths)
    value = draw(value_in(width, low))
    raw = logical(kind, value, width)
    return value, raw, len(raw)


@dataclass
class Built:
    path: bytes
    boundaries: list[int]
    """Byte offsets where a segment starts (and the end)."""


def join(*parts: bytes) -> Built:
    boundaries = [0]
    for part in parts:
        boundaries.append(boundaries[-1] + len(part))
    return Built(b"".join(parts), boundaries)


route = st.lists(
    st.one_of(
        st.builds(port, st.integers(1, 14), st.binary(min_size=1, max_size=1)),
        st.builds(port, st.integers(1, 0xFFFF), st.binary(min_size=2, max_size=16)),
    ),
    max_size=2,
)
keys = st.none() | st.builds(
    epath.ElectronicKey,
    st.integers(0, 0xFFFF),
    st.integers(0, 0xFFFF),
    st.integers(0, 0xFFFF),
    st.integers(0, 0xFF),
    st.integers(0, 0xFF),
)


def key_bytes(key: epath.ElectronicKey) -> bytes:
    return bytes((0x34, 0x04)) + struct.pack("<HHHBB", *key)


@st.composite
def connection_paths(
    draw: st.DrawFn,
) -> tuple[Built, int, int, tuple[int, int], epath.ElectronicKey | None, bytes]:
    ports = draw(route)
    key = draw(keys)
    class_id, class_raw, _ = draw(logical_segments(CLASS))
    config, config_raw, _ = draw(logical_segments(INSTANCE))
    o2t, o2t_raw, _ = draw(logical_segments(POINT))
    t2o, t2o_raw, _ = draw(logical_segments(POINT))
    data = draw(st.binary(max_size=8).map(lambda b: b + b"\x00" * (len(b) % 2)))
    parts = [*ports]
    if key is not None:
        parts.append(key_bytes(key))
    parts += [class_raw, config_raw, o2t_raw, t2o_raw]
    if data:
        parts.append(bytes((0x80, len(data) // 2)) + data)
    return join(*parts), class_id, config, (o2t, t2o), key, data


@given(connection_paths())
def test_a_connection_path_in_any_width_decodes_to_the_same_points(
    built: tuple[Built, int, int, tuple[int, int], epath.ElectronicKey | None, bytes],
) -> None:
    path, class_id, config, points, key, data = built
    decoded = epath.decode_connection_path(path.path)
    assert (decoded.class_id, decoded.config_instance, decoded.points) == (
        class_id,
        config,
        points,
    )
    assert decoded.key == key
    assert decoded.config_data == data


@given(connection_paths(), st.data())
def test_a_connection_path_cut_inside_a_segment_is_a_path_error(
    built: tuple[Built, int, int, tuple[int, int], epath.ElectronicKey | None, bytes],
    data: st.DataObject,
) -> None:
    path = built[0]
    inside = [
        cut
        for start, end in zip(path.boundaries, path.boundaries[1:], strict=False)
        for cut in range(start + 1, end)
    ]
    cut = data.draw(st.sampled_from(inside))
    with pytest.raises(PathError):
        epath.decode_connection_path(path.path[:cut])


@given(
    logical_segments(CLASS),
    logical_segments(INSTANCE),
    st.none() | logical_segments(ATTRIBUTE),
    st.none() | logical_segments(MEMBER),
)
def test_a_request_path_in_any_width_decodes_to_the_same_object(
    class_seg: tuple[int, bytes, int],
    instance_seg: tuple[int, bytes, int],
    attribute_seg: tuple[int, bytes, int] | None,
    member_seg: tuple[int, bytes, int] | None,
) -> None:
    raw = class_seg[1] + instance_seg[1]
    raw += attribute_seg[1] if attribute_seg else b""
    raw += member_seg[1] if member_seg else b""
    decoded = epath.decode_request_path(raw)
    assert decoded == epath.RequestPath(
        class_seg[0],
        instance_seg[0],
        attribute_seg[0] if attribute_seg else None,
        member_seg[0] if member_seg else None,
    )


@given(st.integers(0, 0xFFFF), st.integers(0, 0xFFFF_FFFF), st.integers(0, 0xFFFF), widths)
def test_our_encoder_in_every_width_matches_the_layout(
    class_id: int, instance: int, attribute: int, width: int
) -> None:
    fits = [v for v in (class_id, instance, attribute) if v > MAX[width]]
    if fits:
        with pytest.raises(ValueError, match="does not fit"):
            epath.request_path(class_id, instance, attribute, width=width)
        return
    raw = epath.request_path(class_id, instance, attribute, width=width)
    assert raw == logical(CLASS, class_id, width) + logical(INSTANCE, instance, width) + logical(
        ATTRIBUTE, attribute, width
    )
    assert epath.decode_request_path(raw) == epath.RequestPath(class_id, instance, attribute)


def test_the_three_widths_of_the_connection_manager_are_the_same_object() -> None:
    for raw in ("20062401", "2100060025000100", "220006000000260001000000"):
        path = epath.decode_request_path(bytes.fromhex(raw))
        assert (path.class_id, path.instance) == (epath.CLASS_CONNECTION_MANAGER, 1)


UNSUPPORTED_SEGMENTS = [
    "2300",  # logical, reserved format 3
    "3500",  # logical special, not an electronic key
    "3405",  # electronic key, unknown format 5
    "3800",  # logical service ID
    "3c00",  # logical reserved type 7
    "4000",  # network segment
    "6000",  # symbolic segment
    "9103616263",  # ANSI extended symbol: a data segment type we do not take
    "a000",  # data type constructed
    "e000",  # reserved segment type
    "0000",  # port 0
    "1000",  # extended port segment with a link size of 0
]


@pytest.mark.parametrize("segment", UNSUPPORTED_SEGMENTS)
def test_unsupported_segments_are_path_errors_wherever_they_are(segment: str) -> None:
    bad = bytes.fromhex(segment)
    valid = bytes.fromhex("200424972c962c64")
    for where in (0, 2, 4, len(valid)):
        with pytest.raises(PathError):
            epath.decode_connection_path(valid[:where] + bad + valid[where:])
    with pytest.raises(PathError):
        epath.decode_request_path(bytes.fromhex("2004") + bad)


def test_segments_out_of_place_are_path_errors() -> None:
    for raw in (
        "24012004",  # instance before class
        "2004240124022403",  # two instances before a point: a request path takes one
        "200424972c962c648001aaaa2c01",  # a point after the configuration data
    ):
        with pytest.raises(PathError):
            epath.decode_request_path(bytes.fromhex(raw))
    with pytest.raises(PathError):
        epath.decode_connection_path(bytes.fromhex("200424972c962c648001aaaa2c01"))
    with pytest.raises(PathError):
        epath.decode_connection_path(bytes.fromhex("2c96"))  # no class


# --------------------------------------------------------------------------- electronic key

IDENTITY = default_identity()  # vendor 1573, device type 0x2B, product 1013, revision 2.12


@pytest.mark.parametrize(
    ("key", "expected"),
    [
        (epath.ElectronicKey(), None),  # all zero: any device
        (epath.ElectronicKey(1573, 0x2B, 1013, 2, 12), None),  # exact
        (epath.ElectronicKey(1573, 0, 0, 0, 0), None),
        (epath.ElectronicKey(0x0001), ExtendedStatus.VENDOR_PRODUCT_MISMATCH),
        (epath.ElectronicKey(0, 0, 1014), ExtendedStatus.VENDOR_PRODUCT_MISMATCH),
        (epath.ElectronicKey(0, 0x0C), ExtendedStatus.DEVICE_TYPE_MISMATCH),
        (epath.ElectronicKey(0, 0, 0, 3, 0), ExtendedStatus.REVISION_MISMATCH),
        (epath.ElectronicKey(0, 0, 0, 2, 11), ExtendedStatus.REVISION_MISMATCH),  # exact: no
        (epath.ElectronicKey(0, 0, 0, 0x80 | 2, 11), None),  # compatible: we emulate 2.11
        (epath.ElectronicKey(0, 0, 0, 0x80 | 2, 13), ExtendedStatus.REVISION_MISMATCH),
        (epath.ElectronicKey(0, 0, 0, 0x80 | 3, 1), ExtendedStatus.REVISION_MISMATCH),
    ],
)
def test_electronic_key_rules(key: epath.ElectronicKey, expected: int | None) -> None:
    assert key.mismatch(IDENTITY) == expected
    assert epath.decode_connection_path(key.encode() + bytes.fromhex("200424972c962c64")).key == (
        key
    )


# --------------------------------------------------------------------------- at the target


@dataclass
class Session:
    session_handle: int = 1
    peer_host: str = "127.0.0.1"
    local_host: str = "127.0.0.2"


def forward_open(path: bytes) -> bytes:
    request = ForwardOpenRequest(
        o2t_connection_id=0,
        t2o_connection_id=0x1234,
        connection_serial=1,
        vendor_id=0xFFFE,
        originator_serial=2,
        timeout_multiplier=2,
        o2t_rpi_us=10_000,
        o2t_params=NetworkParams(26),
        t2o_rpi_us=10_000,
        t2o_params=NetworkParams(286),
        path=path,
    )
    return request.request().encode()


@st.composite
def malformed_paths(draw: st.DrawFn) -> bytes:
    """A valid connection path spoiled: cut inside a segment, or an unsupported segment put
    somewhere in it. Always an even number of bytes, as a path size in words allows."""
    built, *_ = draw(connection_paths())
    if draw(st.booleans()):
        inside = [
            cut
            for start, end in zip(built.boundaries, built.boundaries[1:], strict=False)
            for cut in range(start + 1, end)
            if cut % 2 == 0
        ]
        if inside:
            return built.path[: draw(st.sampled_from(inside))]
    where = draw(st.sampled_from(built.boundaries))
    bad = bytes.fromhex(draw(st.sampled_from(UNSUPPORTED_SEGMENTS)))
    bad += b"\x00" * (len(bad) % 2)
    return built.path[:where] + bad + built.path[where:]


@settings(max_examples=150, deadline=None)
@given(malformed_paths())
def test_the_target_answers_malformed_paths_with_statuses(path: bytes) -> None:
    """A Forward Open with a malformed connection path gets 0x01 / 0x0315; an explicit request
    or a Forward Open with a malformed request path gets 0x04. Nothing raises; every refused
    Forward Open is counted under its status."""
    target = Target(TargetSettings(host="127.0.0.1", tcp_port=0), StaticRobot())
    response_bytes, extra = target.handle_unconnected(forward_open(path), [], Session())
    response = cip.decode_response(response_bytes)
    assert (response.general_status, response.additional_status) == (
        GeneralStatus.CONNECTION_FAILURE,
        (ExtendedStatus.INVALID_SEGMENT_IN_PATH,),
    )
    assert extra == []
    for service in (Service.GET_ATTRIBUTE_SINGLE, Service.FORWARD_OPEN):
        request = MessageRouterRequest(service, path)
        response = cip.decode_response(
            target.handle_unconnected(request.encode(), [], Session())[0]
        )
        assert response.general_status in (
            GeneralStatus.PATH_SEGMENT_ERROR,
            GeneralStatus.PATH_DESTINATION_UNKNOWN,  # a route cut just after a class segment
            GeneralStatus.OBJECT_DOES_NOT_EXIST,
        )
    counts = {
        (r.general_status, r.extended_status): r.count for r in target.forward_open_refusals()
    }
    assert counts[GeneralStatus.CONNECTION_FAILURE, ExtendedStatus.INVALID_SEGMENT_IN_PATH] == 1
    assert target.counters.forward_open_refusals == 2
    assert target.connections() == []
