"""The codec against hand-built golden vectors, and round-trip properties (Hypothesis)."""

from __future__ import annotations

import json
import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_hmi.codec import (
    CodecError,
    CommandImage,
    Frame,
    FrameSizeError,
    command_from_json,
    command_to_json,
    decode_command,
    decode_frame,
    dumps,
    encode_command,
    encode_frame,
    frame_from_json,
    frame_to_json,
    zero_command,
)
from cobot_hmi.generated.frames import O2T_COUNTS, T2O_COUNTS, ControllerVersion
from cobot_hmi.layout import O2T_ASSEMBLY, T2O_ASSEMBLY, used_bit_mask
from golden_vectors import GOLDEN_DIR, Vector, o2t_vectors, t2o_vectors

T2O = t2o_vectors()
O2T = o2t_vectors()


def _json_roundtrip(data: object) -> object:
    """What a browser receives: the serialized JSON form parsed back."""
    return json.loads(dumps(data))


# --------------------------------------------------------------------------- golden vectors


@pytest.mark.parametrize("vector", [*T2O, *O2T], ids=lambda v: v.name)
def test_committed_golden_files_match_the_hand_built_vectors(vector: Vector) -> None:
    assert (GOLDEN_DIR / f"{vector.name}.hex").read_text().strip() == vector.wire.hex()
    committed = json.loads((GOLDEN_DIR / f"{vector.name}.json").read_text())
    assert committed == vector.expected_json


@pytest.mark.parametrize("vector", T2O, ids=lambda v: v.name)
def test_t2o_golden_decodes_to_the_expected_json(vector: Vector) -> None:
    wire = bytes.fromhex((GOLDEN_DIR / f"{vector.name}.hex").read_text())
    expected = json.loads((GOLDEN_DIR / f"{vector.name}.json").read_text())
    frame = decode_frame(wire)
    assert _json_roundtrip(frame_to_json(frame)) == expected
    assert list(frame_to_json(frame)) == list(expected)  # canonical names, in order
    assert encode_frame(frame) == wire


@pytest.mark.parametrize("vector", O2T, ids=lambda v: v.name)
def test_o2t_golden_decodes_to_the_expected_json(vector: Vector) -> None:
    wire = bytes.fromhex((GOLDEN_DIR / f"{vector.name}.hex").read_text())
    expected = json.loads((GOLDEN_DIR / f"{vector.name}.json").read_text())
    image = decode_command(wire)
    assert _json_roundtrip(command_to_json(image)) == expected
    assert encode_command(image) == wire


def test_mid_motion_frame_reads_as_the_spec_says() -> None:
    frame = decode_frame(T2O[1].wire)
    assert frame.controlbox_di[0] and frame.controlbox_di[2] and not frame.controlbox_di[1]
    assert frame.controlbox_do[2] and sum(frame.controlbox_do) == 1
    assert frame.tool_do == (True, False, False, False, False, True)
    assert frame.analog_input_type == (0, 1) and frame.analog_output_type == (1, 0)
    assert frame.robot_state == 14 and frame_to_json(frame)["robot_state_name"] == (
        "STANDALONE_RUNNING"
    )
    assert frame.servo_on and not frame.emergency_stopped
    assert frame.controller_version == ControllerVersion(2, 12, 3)
    assert frame.bit_output_registers[40] and frame.bit_output_registers[63]
    assert frame.joint_position[0] == 30.5


def test_unknown_robot_state_decodes_as_unknown() -> None:
    wire = bytearray(284)
    wire[32] = 200
    frame = decode_frame(bytes(wire))
    assert frame.robot_state == 200
    assert frame_to_json(frame)["robot_state_name"] == "UNKNOWN"


def test_non_finite_reals_serialize_as_null() -> None:
    frame = decode_frame(T2O[2].wire)
    assert math.isnan(frame.joint_position[0]) and frame.joint_position[1] == math.inf
    parsed = _json_roundtrip(frame_to_json(frame))
    assert isinstance(parsed, dict)
    assert parsed["joint_position"][:3] == [None, None, None]


# --------------------------------------------------------------------------- sizes


def test_longer_frame_keeps_the_rest_as_extra() -> None:
    tail = bytes(range(1, 33))
    frame = decode_frame(T2O[1].wire + tail)
    assert frame.extra == tail
    assert frame._replace(extra=b"") == decode_frame(T2O[1].wire)
    assert encode_frame(frame) == T2O[1].wire + tail
    assert frame_to_json(frame)["extra"] == tail.hex()
    assert "extra" not in frame_to_json(decode_frame(T2O[1].wire))


@pytest.mark.parametrize("size", [0, 1, 283])
def test_short_frame_names_expected_and_actual_size(size: int) -> None:
    with pytest.raises(FrameSizeError, match=f"expected 284 bytes, got {size}") as caught:
        decode_frame(bytes(size))
    assert (caught.value.expected, caught.value.actual) == (284, size)


@pytest.mark.parametrize("size", [19, 21])
def test_command_image_must_be_exactly_20_bytes(size: int) -> None:
    with pytest.raises(FrameSizeError, match=f"expected 20 bytes, got {size}"):
        decode_command(bytes(size))


def test_decode_accepts_memoryview_and_bytearray() -> None:
    wire = T2O[1].wire
    assert decode_frame(memoryview(wire)) == decode_frame(bytearray(wire))


# --------------------------------------------------------------------------- JSON → image


def test_partial_command_image_sets_only_what_it_names() -> None:
    image = command_from_json(
        {
            "controlbox_do": {"2": True},
            "bit_input_registers": {"40": True},
            "analog_output": {"1": 5},
        }
    )
    assert image.controlbox_do[2] and sum(image.controlbox_do) == 1
    assert image.bit_input_registers[40] and sum(image.bit_input_registers) == 1
    assert image.analog_output == (0.0, 5.0)
    assert encode_command(image) == bytes.fromhex(
        "04000000" + "00000000" + "0000a040"
    ) + struct.pack("<Q", 1 << 40)


def test_partial_image_over_a_base_keeps_the_base() -> None:
    base = command_from_json({"controlbox_do": {"0": True}, "analog_output": [4.0, 4.0]})
    image = command_from_json({"controlbox_do": {"1": True}}, base=base)
    assert image.controlbox_do[:3] == (True, True, False)
    assert image.analog_output == (4.0, 4.0)


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ({"controlbox_dx": {}}, "unknown field 'controlbox_dx'"),
        ({"controlbox_do": {"16": True}}, r"controlbox_do\[16\]: index out of range 0–15"),
        ({"bit_input_registers": {"64": True}}, "index out of range 0–63"),
        ({"tool_do": {"-1": True}}, "not a whole number"),
        ({"tool_do": {"x": True}}, "not a whole number"),
        # Index keys are ASCII decimal in canonical form: other scripts' digits, superscripts,
        # signs, spaces and leading zeros are refused, not read as an index.
        ({"controlbox_do": {"٣": True}}, "not a whole number"),
        ({"controlbox_do": {"１": True}}, "not a whole number"),
        ({"controlbox_do": {"²": True}}, "not a whole number"),
        ({"controlbox_do": {"+3": True}}, "not a whole number"),
        ({"controlbox_do": {" 3": True}}, "not a whole number"),
        ({"controlbox_do": {"03": True}}, "index '03' has a leading zero"),
        ({"controlbox_do": {"00": True}}, "leading zero"),
        ({"controlbox_do": {"9" * 5000: True}}, "index out of range 0–15"),
        ({"controlbox_do": {"0": 1}}, "expected true or false"),
        ({"analog_output": {"0": math.inf}}, "not a finite number"),
        ({"analog_output": {"1": math.nan}}, "not a finite number"),
        ({"analog_output": {"0": None}}, "not a finite number"),
        ({"analog_output": {"0": "5"}}, "expected a number"),
        ({"analog_output_type": {"0": 2}}, "expected 0 to 1"),
        ({"analog_output_type": {"0": True}}, "expected an integer"),
        ({"analog_output": [1.0]}, "expected 2 values, got 1"),
        ({"controlbox_do": True}, "expected an array or an index map"),
        ([1, 2], "expected a JSON object"),
    ],
)
def test_bad_command_json_is_refused_with_the_field_named(body: object, message: str) -> None:
    with pytest.raises(CodecError, match=message):
        command_from_json(body)


def test_frame_json_round_trip_through_from_json() -> None:
    frame = decode_frame(T2O[1].wire)
    assert frame_from_json(frame_to_json(frame)) == frame
    assert frame_from_json({}) == decode_frame(bytes(284))


# --------------------------------------------------------------------------- properties

_BOOL = st.booleans()
_F32 = st.floats(width=32, allow_nan=True, allow_infinity=True)


def _tuple(element: st.SearchStrategy[object], count: int) -> st.SearchStrategy[tuple[object, ...]]:
    return st.tuples(*[element] * count)


def _elements(kind: str) -> st.SearchStrategy[object]:
    return {"bool": _BOOL, "int": st.integers(0, 1), "float": _F32}[kind]


@st.composite
def frames(draw: st.DrawFn) -> Frame:
    values: dict[str, object] = {}
    for f in T2O_ASSEMBLY.fields:
        if f.element_names:
            values[f.name] = ControllerVersion(*draw(st.tuples(*[st.integers(0, 255)] * 3)))
        elif f.enum:
            values[f.name] = draw(st.integers(0, 255))
        elif f.scalar:
            values[f.name] = draw(_BOOL)
        else:
            values[f.name] = draw(_tuple(_elements(f.value_kind), f.count))
    values["extra"] = draw(st.binary(max_size=64))
    return Frame(**values)  # type: ignore[arg-type]


@st.composite
def command_images(draw: st.DrawFn) -> CommandImage:
    values = {f.name: draw(_tuple(_elements(f.value_kind), f.count)) for f in O2T_ASSEMBLY.fields}
    return CommandImage(**values)  # type: ignore[arg-type]


def _same(a: object, b: object) -> bool:
    """Equality where NaN equals NaN (the typed frames hold floats)."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def _quiet_nans(wire: bytes, assembly_fields: tuple[tuple[int, int], ...]) -> bytes:
    """Set the quiet bit of every float32 NaN: CPython's float conversion quiets signalling NaNs."""
    out = bytearray(wire)
    for offset, count in assembly_fields:
        for i in range(count):
            at = offset + 4 * i
            (bits,) = struct.unpack_from("<I", out, at)
            if bits & 0x7F800000 == 0x7F800000 and bits & 0x007FFFFF:
                struct.pack_into("<I", out, at, bits | 0x00400000)
    return bytes(out)


def _real_spans(fields: tuple[object, ...]) -> tuple[tuple[int, int], ...]:
    return tuple(
        (f.offset, f.count)  # type: ignore[attr-defined]
        for f in fields
        if f.value_kind == "float"  # type: ignore[attr-defined]
    )


@settings(max_examples=300)
@given(frames())
def test_decode_inverts_encode_for_any_frame(frame: Frame) -> None:
    assert _same(tuple(decode_frame(encode_frame(frame))), tuple(frame))


@settings(max_examples=300)
@given(command_images())
def test_decode_inverts_encode_for_any_command_image(image: CommandImage) -> None:
    assert _same(tuple(decode_command(encode_command(image))), tuple(image))


def _masked(raw: bytes, mask: bytes) -> bytes:
    return bytes(b & m for b, m in zip(raw, mask, strict=True))


@settings(max_examples=300)
@given(st.binary(min_size=284, max_size=284))
def test_encode_inverts_decode_for_any_buffer_with_zero_reserved_bits(raw: bytes) -> None:
    wire = _quiet_nans(_masked(raw, used_bit_mask(T2O_ASSEMBLY)), _real_spans(T2O_ASSEMBLY.fields))
    assert encode_frame(decode_frame(wire)) == wire


@settings(max_examples=300)
@given(st.binary(min_size=20, max_size=20))
def test_encode_inverts_decode_for_any_command_buffer_with_zero_reserved_bits(raw: bytes) -> None:
    wire = _quiet_nans(_masked(raw, used_bit_mask(O2T_ASSEMBLY)), _real_spans(O2T_ASSEMBLY.fields))
    assert encode_command(decode_command(wire)) == wire


def test_signalling_nan_comes_back_quiet_as_documented() -> None:
    wire = bytearray(284)
    struct.pack_into("<I", wire, 36, 0x7F800001)  # joint 1 position: a signalling NaN
    frame = decode_frame(bytes(wire))
    assert math.isnan(frame.joint_position[0])
    assert struct.unpack_from("<I", encode_frame(frame), 36)[0] == 0x7FC00001


def test_reserved_bits_are_ignored_on_decode_and_zero_on_encode() -> None:
    wire = bytearray(T2O[1].wire)
    wire[31] = wire[33] = 0xFF  # reserved bytes
    wire[35] = 0xFF  # flags word, bits 24-31: reserved
    assert encode_frame(decode_frame(bytes(wire))) == T2O[1].wire


def test_encode_refuses_arrays_of_the_wrong_length() -> None:
    frame = decode_frame(T2O[1].wire)
    with pytest.raises(ValueError, match="joint_position has 5 values, expected 6"):
        encode_frame(frame._replace(joint_position=frame.joint_position[:5]))
    with pytest.raises(ValueError, match="tool_do has 7 values"):
        encode_command(zero_command()._replace(tool_do=(False,) * 7))


def test_counts_cover_every_array_field() -> None:
    assert set(T2O_COUNTS) == {f.name for f in T2O_ASSEMBLY.fields if not f.scalar}
    assert set(O2T_COUNTS) == {f.name for f in O2T_ASSEMBLY.fields}


def test_index_keys_in_canonical_form_are_applied() -> None:
    image = command_from_json({"controlbox_do": {"0": True, "15": True}, "tool_do": {1: True}})
    assert image.controlbox_do[0] and image.controlbox_do[15]
    assert image.tool_do[1] is True
