"""Layer: codec (pure, no I/O). Imports only the layout and its generated frames.

Decode and encode the two assemblies. The per-field work is in ``generated/frames.py``, which
``cobot_hmi.codegen`` derives from the layout table with one precompiled ``struct`` per
assembly; this module adds the size rules of docs/assembly.md ("Reading decisions", longer frames),
clear errors, and the JSON forms.

JSON has no NaN or infinity: in the serialized form (``dumps``) a non-finite REAL becomes
``null``. The typed frame keeps the value itself. Decoding a float32 to a Python float and back
keeps every value, but a *signalling* NaN comes back quiet (IEEE 754 conversions quiet them,
and CPython converts through a C double), so byte-for-byte round trips hold for quiet NaNs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Final

import orjson

from cobot_hmi.codec_errors import CodecError, FrameSizeError
from cobot_hmi.generated.frames import (
    O2T_COUNTS,
    O2T_SIZE,
    T2O_SIZE,
    CommandImage,
    ControllerVersion,
    Frame,
    decode_o2t,
    decode_t2o,
    encode_o2t,
    encode_t2o,
    o2t_to_dict,
    t2o_to_dict,
)
from cobot_hmi.layout import O2T_ASSEMBLY, T2O_ASSEMBLY, Assembly, Field

__all__ = [
    "O2T_SIZE",
    "T2O_SIZE",
    "CodecError",
    "CommandImage",
    "Frame",
    "FrameSizeError",
    "command_from_json",
    "command_to_json",
    "decode_command",
    "decode_frame",
    "dumps",
    "encode_command",
    "encode_frame",
    "frame_from_json",
    "frame_to_json",
    "zero_command",
    "zero_frame",
]


decode_frame = decode_t2o
"""Decode a T→O frame. Bytes past 284 are kept as ``frame.extra``; fewer raise
``FrameSizeError`` naming the expected and actual sizes. (The generated decoder itself: no
wrapper call on the hot path.)"""

decode_command = decode_o2t
"""Decode an O→T command image, which is exactly 20 bytes (``FrameSizeError`` otherwise)."""


def encode_frame(frame: Frame) -> bytes:
    """The wire bytes of a T→O frame, its ``extra`` bytes appended."""
    return encode_t2o(frame) + frame.extra


def encode_command(image: CommandImage) -> bytes:
    """The 20 wire bytes of an O→T command image."""
    return encode_o2t(image)


_ZERO_FRAME: Final = decode_t2o(bytes(T2O_SIZE))
_ZERO_COMMAND: Final = decode_o2t(bytes(O2T_SIZE))


def zero_frame() -> Frame:
    """A T→O frame of all zero bytes (robot state 0, every value 0)."""
    return _ZERO_FRAME


def zero_command() -> CommandImage:
    """An O→T image of all zero bytes: every output off, analog types current, value 0."""
    return _ZERO_COMMAND


def frame_to_json(frame: Frame) -> dict[str, object]:
    """The frame's JSON form; ``extra`` (hex) appears only when the frame was longer."""
    data = t2o_to_dict(frame)
    if frame.extra:
        data["extra"] = frame.extra.hex()
    return data


def command_to_json(image: CommandImage) -> dict[str, object]:
    """The command image's JSON form."""
    return o2t_to_dict(image)


def dumps(data: object) -> bytes:
    """Serialize a JSON form: tuples as arrays, non-finite floats as ``null``."""
    return orjson.dumps(data)


# --------------------------------------------------------------------------- from JSON


def _element(f: Field, where: str, value: object) -> bool | int | float:
    """Check one JSON element against its field's kind; a clear ``CodecError`` otherwise."""
    kind = f.value_kind
    if kind == "bool":
        if isinstance(value, bool):
            return value
        raise CodecError(f"{where}: expected true or false, got {value!r}")
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise CodecError(f"{where}: expected an integer, got {value!r}")
        limit = len(f.value_names) if f.value_names else 256
        if not 0 <= value < limit:
            raise CodecError(f"{where}: expected 0 to {limit - 1}, got {value}")
        return value
    if value is None:  # the serialized form of a non-finite REAL
        return math.nan
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CodecError(f"{where}: expected a number, got {value!r}")
    return float(value)


_MAX_INDEX_DIGITS: Final = 6
"""Longer index keys are out of range for every field; not converted (a huge digit string
would cost quadratic time in ``int``)."""


def _index(f: Field, key: object) -> int:
    """An index-map key: ASCII decimal digits in canonical form, or a Python ``int``.

    ``str.isdigit`` (and ``int``) also accept other scripts' digits ("٣", "１") and
    superscripts ("²" passes ``isdigit`` but fails ``int``): only ``0``–``9`` are taken. Leading
    zeros are refused ("03"): otherwise two keys of one JSON object ("3" and "03") could name
    the same element, and which one won would depend on member order; the audit trail also
    records the canonical ``name.index`` key, which then always is what the client sent.
    """
    if isinstance(key, int) and not isinstance(key, bool):
        index = key
        if index < 0:
            raise CodecError(f"{f.name}: index {key!r} is not a whole number")
    else:
        text = key if isinstance(key, str) else None
        if text is None or not text.isascii() or not text.isdigit():
            raise CodecError(f"{f.name}: index {key!r} is not a whole number (ASCII digits 0–9)")
        if len(text) > 1 and text[0] == "0":
            canonical = text.lstrip("0") or "0"
            raise CodecError(f"{f.name}: index {key!r} has a leading zero (write {canonical!r})")
        if len(text) > _MAX_INDEX_DIGITS:
            shown = text[:_MAX_INDEX_DIGITS] + "…"
            raise CodecError(f"{f.name}[{shown}]: index out of range 0–{f.count - 1}")
        index = int(text)
    if index >= f.count:
        raise CodecError(f"{f.name}[{index}]: index out of range 0–{f.count - 1}")
    return index


def _values_from_json(f: Field, value: object, base: tuple[object, ...]) -> tuple[object, ...]:
    """A field's new tuple: a full JSON array, or a map from index to value over ``base``."""
    if isinstance(value, list | tuple):
        if len(value) != f.count:
            raise CodecError(f"{f.name}: expected {f.count} values, got {len(value)}")
        return tuple(_element(f, f"{f.name}[{i}]", v) for i, v in enumerate(value))
    if isinstance(value, Mapping):
        items = list(base)
        for key, element in value.items():
            index = _index(f, key)
            items[index] = _element(f, f"{f.name}[{index}]", element)
        return tuple(items)
    raise CodecError(f"{f.name}: expected an array or an index map, got {value!r}")


def _fields_from_json(
    assembly: Assembly, data: object, base: tuple[object, ...]
) -> tuple[object, ...]:
    if not isinstance(data, Mapping):
        raise CodecError(f"{assembly.name}: expected a JSON object, got {type(data).__name__}")
    by_name = {f.name: (i, f) for i, f in enumerate(assembly.fields)}
    derived = {f"{f.name}_name" for f in assembly.fields if f.enum} | {"extra"}
    unknown = sorted(k for k in data if k not in by_name and k not in derived)
    if unknown:
        raise CodecError(f"unknown field {unknown[0]!r} (not in the {assembly.name} layout)")
    values = list(base)
    for name, value in data.items():
        if name in derived:
            continue
        position, f = by_name[name]
        if f.element_names:
            if not isinstance(value, Mapping):
                raise CodecError(f"{name}: expected an object with {', '.join(f.element_names)}")
            missing = [n for n in f.element_names if n not in value]
            if missing:
                raise CodecError(f"{name}: missing {missing[0]}")
            elements = (_element(f, f"{name}.{n}", value[n]) for n in f.element_names)
            values[position] = ControllerVersion(*(int(e) for e in elements))
        elif f.scalar:
            values[position] = _element(f, name, value)
        else:
            current = values[position]
            assert isinstance(current, tuple)
            values[position] = _values_from_json(f, value, current)
    return tuple(values)


def frame_from_json(data: object) -> Frame:
    """A frame from its JSON form (missing fields are zero); the emulator and tests use it."""
    base = tuple(_ZERO_FRAME)
    values = _fields_from_json(T2O_ASSEMBLY, data, base[:-1])
    extra = data.get("extra", "") if isinstance(data, Mapping) else ""
    try:
        extra_bytes = bytes.fromhex(str(extra))
    except ValueError as error:
        raise CodecError(f"extra: not hex ({error})") from None
    return Frame._make((*values, extra_bytes))


def command_from_json(data: object, base: CommandImage | None = None) -> CommandImage:
    """An O→T image from JSON: full arrays or index maps; what is missing keeps ``base``.

    With no ``base`` missing fields are zero. Unknown fields, out-of-range indexes, wrong types
    and non-finite floats raise ``CodecError`` naming the field; nothing is half-applied.
    """
    start = base if base is not None else _ZERO_COMMAND
    values = _fields_from_json(O2T_ASSEMBLY, data, tuple(start))
    image = CommandImage._make(values)
    for name in O2T_COUNTS:
        for i, v in enumerate(getattr(image, name)):
            if isinstance(v, float) and not math.isfinite(v):
                raise CodecError(f"{name}[{i}]: {v} is not a finite number")
    return image
