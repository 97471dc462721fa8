"""Layer: layout tooling. Writes ``generated/frames.py``: the typed frames and their codec.

The decoder is the backend's hot path (one call per received frame), so its shape is chosen for
speed: one ``unpack_from`` per frame, table look-ups for bits, ``itemgetter`` runs for REAL
arrays. ``bench/codec`` measures it against a bare ``unpack_from``.
"""

from __future__ import annotations

import re
from typing import Final

from cobot_hmi.codegen.common import HEADER, quoted
from cobot_hmi.codegen.struct_plan import BitChunk, bit_chunks, item_index, slots, struct_format
from cobot_hmi.layout import (
    ASSEMBLIES,
    LAYOUT_VERSION,
    ROBOT_STATES,
    T2O_ASSEMBLY,
    UNKNOWN_STATE_NAME,
    Assembly,
    CipType,
    Field,
)


def _py_type(f: Field) -> str:
    if f.element_names:
        return "ControllerVersion"
    if f.enum:
        return "int"
    element = f.value_kind
    return element if f.scalar else f"tuple[{element}, ...]"


def _class_name(assembly: Assembly) -> str:
    return "Frame" if assembly is T2O_ASSEMBLY else "CommandImage"


def _chunk_expr(value: str, chunk: BitChunk, table: str = "_BITS") -> str:
    """Expression giving the chunk's bits of byte ``value`` as a tuple (booleans or 0/1)."""
    if chunk.shift == 0 and chunk.width == 8 and table == "_BITS":
        return f"_B8[{value}]"
    shifted = f"({value} >> {chunk.shift})" if chunk.shift else value
    if chunk.shift + chunk.width < 8:
        shifted = f"{shifted} & {(1 << chunk.width) - 1:#x}"
    return f"{table}[{chunk.width}][{shifted}]"


def _decode_elements(assembly: Assembly) -> tuple[list[str], list[str], list[str]]:
    """The elements of the decoded tuple, in field order, the module constants they need and
    the statements that come before the tuple (``_memo_lines``).

    Speed matters here (one call per received frame), so runs of REAL arrays come out of one
    ``itemgetter`` of slices, neighbouring flags out of one table look-up, and wide bit arrays
    are spliced rather than concatenated, and taken by their bytes from those decoded lately
    (``_memo_lines``); every element is still derived from the table.
    """
    items = item_index(assembly)
    tag = assembly.direction.value.upper()
    elements: list[str] = []
    constants: list[str] = []
    prelude: list[str] = []
    pending_slices: list[str] = []
    pending_flags: list[BitChunk] = []

    def flush() -> None:
        if len(pending_slices) > 1:
            name = f"_{tag}_RUN_{len(constants)}"
            constants.append(f"{name}: Final = itemgetter({', '.join(pending_slices)})")
            elements.append(f"*{name}(v)")
        elif pending_slices:
            elements.append(f"v[{pending_slices[0].replace('slice(', '').replace(', ', ':')[:-1]}]")
        pending_slices.clear()
        if len(pending_flags) > 1:
            first = pending_flags[0]
            run = BitChunk(first.byte, first.shift, 0, len(pending_flags))
            elements.append("*" + _chunk_expr(f"v[{items[first.byte]}]", run))
        elif pending_flags:
            chunk = pending_flags[0]
            elements.append(f"_TF[({f'v[{items[chunk.byte]}]'} >> {chunk.shift}) & 1]")
        pending_flags.clear()

    for f in assembly.fields:
        if f.cip_type is CipType.BOOL and f.scalar:
            (chunk,) = bit_chunks(f)
            last = pending_flags[-1] if pending_flags else None
            if last and not (last.byte == chunk.byte and last.shift + 1 == chunk.shift):
                flush()
            if pending_slices:
                flush()
            pending_flags.append(chunk)
            continue
        if f.cip_type is not CipType.BOOL and not f.scalar and not f.element_names:
            if pending_flags:
                flush()
            at = items[f.offset]
            pending_slices.append(f"slice({at}, {at + f.count})")
            continue
        flush()
        if f.cip_type is CipType.BOOL:
            table = "_INTS" if f.value_names else "_BITS"
            field_chunks = bit_chunks(f)
            chunks = [_chunk_expr(f"v[{items[c.byte]}]", c, table) for c in field_chunks]
            if len(chunks) > 2:
                start, end = items[field_chunks[0].byte], items[field_chunks[-1].byte] + 1
                spliced = "(" + ", ".join(f"*{c}" for c in chunks) + ")"
                name = f"{f.name}_bits"
                constants += _memo_constant(tag, f.name)
                prelude += _memo_lines(tag, f.name, name, f"v[{start}:{end}]", spliced)
                elements.append(name)
            else:
                elements.append(" + ".join(chunks))
        elif f.element_names:
            at = items[f.offset]
            elements.append(f"_new(ControllerVersion, v[{at}:{at + f.count}])")
        else:
            elements.append(f"v[{items[f.offset]}]")
    flush()
    return elements, constants, prelude


def _memo_constant(tag: str, field: str) -> list[str]:
    return [
        f"_{tag}_{field.upper()}_SEEN: Final[dict[tuple[int, ...], tuple[bool | int, ...]]] = {{}}",
        f'"""``{field}`` by the bytes it came from, as decoded lately (at most'
        f' ``_SEEN_MAX``: a few per robot of a cell; any thread may decode)."""',
    ]


def _memo_lines(tag: str, field: str, name: str, key: str, spliced: str) -> list[str]:
    """A wide bit array (64 booleans from 8 bytes, a spliced tuple of 64 items: 0.5-0.9 µs of
    a frame's 3.5 µs decode) taken from those decoded lately when its bytes are the same: a
    robot's registers change far less often than its frames come, and a cell's robots
    interleave theirs (hence not the last one only)."""
    seen = f"_{tag}_{field.upper()}_SEEN"
    return [
        f"    {field}_key = {key}",
        f"    {name} = {seen}.get({field}_key)",
        f"    if {name} is None:",
        f"        {name} = {spliced}",
        f"        if len({seen}) >= _SEEN_MAX:",
        f"            {seen}.clear()",
        f"        {seen}[{field}_key] = {name}",
    ]


def _encode_args(assembly: Assembly, var: str) -> list[str]:
    parts_by_byte: dict[int, list[str]] = {}
    for f in assembly.fields:
        if f.cip_type is not CipType.BOOL:
            continue
        for c in bit_chunks(f):
            if f.scalar:
                part = f"(int({var}.{f.name}) << {c.shift})"
            else:
                whole = c.first_element == 0 and c.width == f.count
                values = f"{var}.{f.name}"
                if not whole:
                    values += f"[{c.first_element}:{c.first_element + c.width}]"
                part = f"_pack_bits({values}, {c.shift})"
            parts_by_byte.setdefault(c.byte, []).append(part)
    args: list[str] = []
    for slot in slots(assembly):
        first = slot.fields[0]
        if first.cip_type is CipType.BOOL:
            args.append(" | ".join(parts_by_byte[slot.start]))
        else:
            args.append(f"{var}.{first.name}" if first.scalar else f"*{var}.{first.name}")
    return args


def frames_module() -> str:
    out = _module_head()
    out += _typed_frames()
    out += _BIT_HELPERS
    for assembly in ASSEMBLIES:
        out += _assembly_codec(assembly)
    out += [
        "",
        "_STATE_NAMES: Final = {state.value: state.name for state in RobotState}",
        "",
    ]
    return re.sub(r"\n{4,}", "\n\n\n", "\n".join(out))


def _module_head() -> list[str]:
    return [
        f'"""{HEADER}',
        "",
        "Layer: codec (pure, no I/O). The typed frames and their wire form, one struct per",
        "assembly. Use it through ``cobot_hmi.codec``, which adds the size checks and errors.",
        '"""',
        "",
        "from __future__ import annotations",
        "",
        "import struct",
        "from collections.abc import Sequence",
        "from enum import IntEnum",
        "from operator import attrgetter, itemgetter",
        "from typing import Final, NamedTuple",
        "",
        "from cobot_hmi.codec_errors import FrameSizeError",
        "",
        f"LAYOUT_VERSION: Final = {LAYOUT_VERSION}",
        f"UNKNOWN_STATE_NAME: Final = {quoted(UNKNOWN_STATE_NAME)}",
    ]


def _typed_frames() -> list[str]:
    """The state enum, the controller version and one NamedTuple per assembly."""
    out = [
        "",
        "",
        "class RobotState(IntEnum):",
        '    """Robot state (T→O byte 32), as the table on the robot numbers it."""',
        "",
    ]
    out += [f"    {s.name} = {s.value}" for s in ROBOT_STATES]
    out += [
        "",
        "",
        "class ControllerVersion(NamedTuple):",
        '    """Controller software version (T→O bytes 28–30)."""',
        "",
    ]
    version_field = next(f for f in T2O_ASSEMBLY.fields if f.element_names)
    out += [f"    {name}: int" for name in version_field.element_names]
    for assembly in ASSEMBLIES:
        out += ["", "", f"class {_class_name(assembly)}(NamedTuple):"]
        out += [f'    """{assembly.description} ({assembly.size_bytes} bytes)."""', ""]
        for f in assembly.fields:
            unit = f" [{f.unit}]" if f.unit else ""
            out.append(f"    {f.name}: {_py_type(f)}")
            out.append(f'    """{f.description}{unit}."""')
        if assembly is T2O_ASSEMBLY:
            out.append('    extra: bytes = b""')
            out.append('    """Bytes after the 284 the layout describes (longer frames)."""')
    return out


_BIT_HELPERS: Final = [
    "",
    "",
    "_new = tuple.__new__",
    "_TF: Final = (False, True)",
    "_BITS: Final = tuple(",
    "    tuple(tuple(bool(v >> i & 1) for i in range(width)) for v in range(1 << width))",
    "    for width in range(9)",
    ")",
    '"""``_BITS[w][v]``: the ``w`` low bits of ``v`` as booleans, bit 0 first."""',
    "_B8: Final = _BITS[8]",
    "_INTS: Final = tuple(",
    "    tuple(tuple(v >> i & 1 for i in range(width)) for v in range(1 << width))",
    "    for width in range(9)",
    ")",
    '"""``_INTS[w][v]``: the ``w`` low bits of ``v`` as 0/1 codes, bit 0 first."""',
    "_SEEN_MAX: Final = 256",
    '"""Wide bit arrays a decoder keeps by their bytes (cleared when full)."""',
    "",
    "",
    "_PACKED: Final[dict[object, int]] = {",
    "    bits: v for table in _BITS for v, bits in enumerate(table)",
    "}",
    '"""Every tuple of up to 8 booleans (or 0/1) to its bits as an int, bit 0 first."""',
    "",
    "",
    "def _pack_bits(bits: Sequence[bool | int], shift: int) -> int:",
    "    try:",
    "        word = _PACKED.get(bits)  # one look-up for the usual tuple of booleans",
    "    except TypeError:  # unhashable (a list)",
    "        word = None",
    "    if word is None:",
    "        word = 0",
    "        for i, bit in enumerate(bits):",
    "            if bit:",
    "                word |= 1 << i",
    "    return word << shift",
    "",
]
"""The generated module's bit tables and packer, shared by every assembly's codec."""


def _assembly_codec(assembly: Assembly) -> list[str]:
    """One assembly's struct, sizes, ``decode_*``, ``encode_*`` and ``*_to_dict``."""
    cls = _class_name(assembly)
    tag = assembly.direction.value.lower()
    var = "frame" if cls == "Frame" else "image"
    arrays = [f for f in assembly.fields if not f.scalar]
    out = [
        "",
        f"{tag.upper()}_STRUCT: Final = struct.Struct({quoted(struct_format(assembly))})",
        f"_{tag.upper()}_UNPACK: Final = {tag.upper()}_STRUCT.unpack_from",
        f"{tag.upper()}_SIZE: Final = {assembly.size_bytes}",
        f"{tag.upper()}_COUNTS: Final = {{",
    ]
    out += [f"    {quoted(f.name)}: {f.count}," for f in arrays]
    out += ["}", ""]
    out += [
        f"_{tag.upper()}_ARRAYS: Final = attrgetter("
        + ", ".join(quoted(f.name) for f in arrays)
        + ")",
        f"_{tag.upper()}_ARRAY_COUNTS: Final = {tuple(f.count for f in arrays)!r}",
    ]
    elements, constants, prelude = _decode_elements(assembly)
    out += constants
    out += _decode_function(assembly, cls, tag, elements, prelude)
    out += _encode_function(assembly, cls, tag, var)
    out += _to_dict_function(assembly, cls, tag, var)
    return out


def _decode_function(
    assembly: Assembly, cls: str, tag: str, elements: list[str], prelude: list[str]
) -> list[str]:
    size = assembly.size_bytes
    out = ["", "", f"def decode_{tag}(data: bytes | bytearray | memoryview) -> {cls}:"]
    if cls == "Frame":
        out += [
            f'    """Decode a T→O frame: bytes past {size} are kept as ``extra``, fewer is an'
            ' error."""',
            "    size = len(data)",
            f"    if size == {size}:",
            '        extra = b""',
            f"    elif size > {size}:",
            f"        extra = bytes(data[{size}:])",
            "    else:",
            f'        raise FrameSizeError("T→O frame too short", {size}, size)',
        ]
    else:
        out += [
            f'    """Decode an O→T command image, which is exactly {size} bytes."""',
            f"    if len(data) != {size}:",
            f'        raise FrameSizeError("O→T command image", {size}, len(data))',
        ]
    out.append(f"    v = _{tag.upper()}_UNPACK(data)")
    out += prelude
    out += [
        "    return _new(",
        f"        {cls},",
        "        (",
    ]
    out += [f"            {element}," for element in elements]
    if cls == "Frame":
        out.append("            extra,")
    out += ["        ),", "    )", ""]
    return out


def _encode_function(assembly: Assembly, cls: str, tag: str, var: str) -> list[str]:
    out = [
        "",
        f"def encode_{tag}({var}: {cls}) -> bytes:",
        f'    """The {assembly.size_bytes} wire bytes of ``{var}``; reserved bits are zero."""',
        f"    if tuple(map(len, _{tag.upper()}_ARRAYS({var}))) != _{tag.upper()}_ARRAY_COUNTS:",
        f"        for name, count in {tag.upper()}_COUNTS.items():",
        f"            if len(getattr({var}, name)) != count:",
        "                raise ValueError(",
        f'                    f"{{name}} has {{len(getattr({var}, name))}} values, "',
        '                    f"expected {count}"',
        "                )",
        f"    return {tag.upper()}_STRUCT.pack(",
    ]
    out += [f"        {arg}," for arg in _encode_args(assembly, var)]
    out += ["    )", ""]
    return out


def _to_dict_function(assembly: Assembly, cls: str, tag: str, var: str) -> list[str]:
    out = [
        "",
        f"def {tag}_to_dict({var}: {cls}) -> dict[str, object]:",
        '    """The JSON form: the spec\'s canonical names and shapes, in layout order."""',
        "    return {",
    ]
    for f in assembly.fields:
        if f.element_names:
            members = ", ".join(
                f"{quoted(n)}: {var}.{f.name}[{i}]" for i, n in enumerate(f.element_names)
            )
            out.append(f"        {quoted(f.name)}: {{{members}}},")
        else:
            out.append(f"        {quoted(f.name)}: {var}.{f.name},")
        if f.enum:
            state = f"_STATE_NAMES.get({var}.{f.name}, UNKNOWN_STATE_NAME)"
            out.append(f"        {quoted(f.name + '_name')}: {state},")
    out += ["    }", ""]
    return out
