"""Layer: history storage. Imports only the layout, the codec and pyarrow/numpy.

The recording's columns, derived from the layout (never written by hand): ``time`` (the receive
time, ``timestamp[us, UTC]``), ``seq`` (the service's frame counter of that robot, rising by one
per frame and starting again at 1 when the service restarts), ``t2o_sequence`` (the
encapsulation sequence number the frame's T→O packet carried on the wire, in its Sequenced
Address item, CIP Vol 2 §2-6 and §3-4.2: the robot raises it by one per packet, so a step of
more than one between rows shows packets the scanner did not deliver as frames, lost on the
network or held back by the receive rules as no new data, where a step of ``seq`` shows frames
the service itself lost; ``uint32``, null in rows recorded before the column existed), then one
column per element of the T→O assembly in the layout's order, named ``field`` for a scalar
field and
``field.index`` (0-based, as the API's element keys) otherwise. REALs are ``float32`` (the
wire's own width: nothing is lost, nothing is widened), USINTs and coded bits (the analog types,
the robot state enum) ``uint8``, flags and digital I/O ``bool`` (Parquet packs them to a bit
each and run-length encodes them). Each column carries its unit and description as field
metadata, so a Parquet export is self-describing.

Exports name an element as the screen labels it (``Element.export_name``): the field and the
channel's label without its spaces, ``joint_position.J1`` for ``joint_position.0`` (J 1),
``controlbox_do.DO3``, ``tool_di.ToolDI1``, ``analog_input.AI0``, ``tcp_position.X``,
``bit_output_registers.Register40``, ``controller_version.major``; a scalar field keeps its name
(``robot_state``). The recording's own segments keep the 0-based names (the API's element keys);
a file read back (``raw_from_columns``) may use either.

Frames are converted whole batches at a time: the recorder's journal keeps the T→O payloads
the frames were decoded from (``journal_form``: nothing is encoded again) and this module
slices the columns out of the ``(n, 284)`` byte matrix with numpy, by the layout's offsets and
bit positions, one gather per kind of column (``column_arrays``); the reverse (columns → bytes,
for replay) is the same table read the other way.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from cobot_hmi.codec import T2O_SIZE, Frame, encode_frame
from cobot_hmi.layout import T2O_ASSEMBLY, CipType, Field

TIME: Final = "time"
"""Receive time column (``timestamp[us, UTC]``)."""
SEQ: Final = "seq"
"""Frame counter column (``int64``)."""
T2O_SEQUENCE: Final = "t2o_sequence"
"""The T→O packet's encapsulation sequence number column (``uint32``, nullable)."""

TIME_TYPE: Final = pa.timestamp("us", tz="UTC")

U8 = npt.NDArray[np.uint8]


@dataclass(frozen=True, slots=True)
class Element:
    """One column of the recording: one element of a layout field."""

    name: str
    """Canonical column name: ``joint_position.0``, or ``robot_state`` for a scalar field."""
    field: Field
    index: int
    kind: str
    """``float``, ``int`` or ``bool`` (the layout's value kind)."""
    label: str
    """The channel's label (``J 1``), else the field's description."""
    export_name: str
    """The column's name in an export: ``joint_position.J1`` (module docstring)."""

    @property
    def unit(self) -> str:
        return self.field.unit

    @property
    def arrow_type(self) -> pa.DataType:
        if self.kind == "float":
            return pa.float32()
        if self.kind == "int":
            return pa.uint8()
        return pa.bool_()

    @property
    def bit(self) -> int:
        """Absolute wire bit of a packed BOOL element (offset·8 + bit)."""
        return self.field.first_wire_bit + self.index

    @property
    def byte_offset(self) -> int:
        """Wire byte offset of a REAL or USINT element."""
        size = 4 if self.field.cip_type is CipType.REAL else 1
        return self.field.offset + size * self.index


def _export_name(f: Field, index: int) -> str:
    if f.scalar:
        return f.name
    if f.channels:
        return f"{f.name}.{f.channels[index].replace(' ', '')}"
    if f.element_names:
        return f"{f.name}.{f.element_names[index]}"
    return f"{f.name}.{index}"


def _elements() -> tuple[Element, ...]:
    out = []
    for f in T2O_ASSEMBLY.fields:
        for index in range(f.count):
            name = f.name if f.scalar else f"{f.name}.{index}"
            label = f.channels[index] if f.channels else f.description
            out.append(Element(name, f, index, f.value_kind, label, _export_name(f, index)))
    return tuple(out)


ELEMENTS: Final = _elements()
"""Every element of the T→O assembly, in the layout's order."""
ELEMENT_BY_NAME: Final = {e.name: e for e in ELEMENTS}
ELEMENT_BY_EXPORT_NAME: Final = {e.export_name: e for e in ELEMENTS}
assert len(ELEMENT_BY_EXPORT_NAME) == len(ELEMENTS), "two elements share an export name"
FIELD_NAMES: Final = tuple(f.name for f in T2O_ASSEMBLY.fields)


def _schema() -> pa.Schema:
    fields = [
        pa.field(TIME, TIME_TYPE, nullable=False, metadata={"description": "receive time"}),
        pa.field(SEQ, pa.int64(), nullable=False, metadata={"description": "frame counter"}),
        pa.field(
            T2O_SEQUENCE,
            pa.uint32(),
            metadata={"description": "the T→O packet's encapsulation sequence number"},
        ),
    ]
    for e in ELEMENTS:
        meta = {"unit": e.unit, "description": e.field.description, "label": e.label}
        fields.append(pa.field(e.name, e.arrow_type, nullable=False, metadata=meta))
    return pa.schema(fields, metadata={"layout": T2O_ASSEMBLY.name})


SCHEMA: Final = _schema()


class UnknownFieldError(ValueError):
    """A field or element name the layout does not have."""

    def __init__(self, name: str) -> None:
        self.name = name
        super().__init__(
            f"unknown field {name!r}: expected a T→O field name (e.g. joint_position) or an "
            "element (e.g. joint_position.2)"
        )


def select_elements(names: Iterable[str] | None) -> list[Element]:
    """The elements named: a field name stands for all its elements, ``field.i`` for one;
    ``None`` or nothing: every element. Order kept, duplicates dropped."""
    wanted = [n.strip() for n in names or () if n.strip()]
    if not wanted:
        return list(ELEMENTS)
    out: dict[str, Element] = {}
    for name in wanted:
        element = ELEMENT_BY_NAME.get(name)
        if element is not None:
            out.setdefault(element.name, element)
            continue
        matched = [e for e in ELEMENTS if e.field.name == name]
        if not matched:
            raise UnknownFieldError(name)
        for e in matched:
            out.setdefault(e.name, e)
    return list(out.values())


# --------------------------------------------------------------------------- frames ↔ columns


def frames_to_raw(frames: Iterable[Frame]) -> U8:
    """The frames' 284 wire bytes each, as an ``(n, 284)`` matrix (``extra`` bytes dropped)."""
    blob = b"".join([encode_frame(f)[:T2O_SIZE] for f in frames])
    return np.frombuffer(blob, dtype=np.uint8).reshape(-1, T2O_SIZE)


def time_us(time_s: npt.ArrayLike) -> npt.NDArray[np.int64]:
    """Epoch seconds → whole microseconds (the ``time`` column's unit)."""
    return np.rint(np.asarray(time_s, dtype=np.float64) * 1e6).astype(np.int64)


FRAME_DTYPE: Final = np.dtype(
    {
        "names": [f.name for f in T2O_ASSEMBLY.fields if f.cip_type is not CipType.BOOL],
        "formats": [
            ("<f4" if f.cip_type is CipType.REAL else "u1", (f.count,))
            for f in T2O_ASSEMBLY.fields
            if f.cip_type is not CipType.BOOL
        ],
        "offsets": [f.offset for f in T2O_ASSEMBLY.fields if f.cip_type is not CipType.BOOL],
        "itemsize": T2O_SIZE,
    }
)
"""A T→O frame's numeric fields as a numpy structured dtype, generated from the layout: a byte
matrix viewed through it gives every REAL and USINT field as an ``(n, count)`` array without a
copy (the packed BOOL bits are shifted out of their bytes)."""


def columns_from_raw(raw: U8) -> dict[str, np.ndarray]:
    """Every element's column, sliced out of an ``(n, 284)`` byte matrix (``FRAME_DTYPE``)."""
    frames = np.ascontiguousarray(raw).view(FRAME_DTYPE).reshape(raw.shape[0])
    out: dict[str, np.ndarray] = {}
    for e in ELEMENTS:
        f = e.field
        if f.cip_type is CipType.BOOL:
            bits = (raw[:, e.bit >> 3] >> (e.bit & 7)) & 1
            out[e.name] = bits.astype(np.uint8) if e.kind == "int" else bits.astype(np.bool_)
        else:
            out[e.name] = np.ascontiguousarray(frames[f.name][:, e.index])
    return out


def _gather_plan() -> tuple[
    npt.NDArray[np.intp], npt.NDArray[np.intp], tuple[int, ...], tuple[tuple[int, int], ...]
]:
    """Where each element's column comes from in one gather per kind (see ``column_arrays``):
    the REALs' byte indexes (4 a column), the bool columns' wire bits, the uint8 columns'
    sources (a byte, or a coded BOOL's bit: -1 - bit), and per element its (kind, row)."""
    real_bytes: list[int] = []
    bool_bits: list[int] = []
    uint8_sources: list[int] = []
    order: list[tuple[int, int]] = []
    for e in ELEMENTS:
        cip_type = e.field.cip_type
        if cip_type is CipType.REAL:
            order.append((0, len(real_bytes) // 4))
            real_bytes.extend(range(e.byte_offset, e.byte_offset + 4))
        elif cip_type is CipType.USINT or e.kind == "int":
            order.append((2, len(uint8_sources)))
            uint8_sources.append(e.byte_offset if cip_type is CipType.USINT else -1 - e.bit)
        else:
            order.append((1, len(bool_bits)))
            bool_bits.append(e.bit)
    return (
        np.asarray(real_bytes, dtype=np.intp),
        np.asarray(bool_bits, dtype=np.intp),
        tuple(uint8_sources),
        tuple(order),
    )


_REAL_BYTES, _BOOL_BITS, _UINT8_SOURCES, _ELEMENT_ROWS = _gather_plan()


def column_arrays(raw: U8) -> list[pa.Array]:
    """Every element's Arrow column (the layout's order) from an ``(n, 284)`` byte matrix, in
    one numpy gather per kind (the REALs, the bools packed to Arrow's bits, the uint8s) into a
    row per column, each column a zero-copy slice of its kind's buffer: a second of 100 frames
    costs a third of slicing the columns one by one (``columns_from_raw``, the same values)."""
    n = raw.shape[0]
    bits = np.unpackbits(raw, axis=1, bitorder="little")  # wire bit b of a frame: bits[:, b]
    reals = np.ascontiguousarray(raw[:, _REAL_BYTES]).view("<f4").T.copy()
    packed = np.packbits(bits[:, _BOOL_BITS].T, axis=1, bitorder="little")
    bool_row_bytes = packed.shape[1]
    uint8s = np.empty((len(_UINT8_SOURCES), n), dtype=np.uint8)
    for row, source in enumerate(_UINT8_SOURCES):
        uint8s[row] = raw[:, source] if source >= 0 else bits[:, -1 - source]
    buffers = (
        pa.py_buffer(reals),
        pa.py_buffer(np.ascontiguousarray(packed)),
        pa.py_buffer(uint8s),
    )
    types = (pa.float32(), pa.bool_(), pa.uint8())
    row_bytes = (4 * n, bool_row_bytes, n)
    return [
        pa.Array.from_buffers(
            types[kind], n, [None, buffers[kind].slice(row * row_bytes[kind], row_bytes[kind])]
        )
        for kind, row in _ELEMENT_ROWS
    ]


def raw_to_batch(
    seq: npt.ArrayLike,
    time_s: npt.ArrayLike,
    raw: U8,
    t2o_sequence: npt.ArrayLike,
    schema: pa.Schema = SCHEMA,
) -> pa.RecordBatch:
    """A record batch of the recording's schema from counters, times, the packets' wire
    sequence numbers and the frames' wire bytes."""
    times_us = time_us(time_s)
    arrays = [
        # Straight onto the numbers' buffer: ``pa.array(…).cast(TIME_TYPE)`` took a tenth of
        # the recorder's cost per batch (the cast resolves the zone every call).
        pa.Array.from_buffers(TIME_TYPE, len(times_us), [None, pa.py_buffer(times_us)]),
        pa.array(np.asarray(seq, dtype=np.int64)),
        pa.array(np.asarray(t2o_sequence, dtype=np.uint32)),
        *column_arrays(np.ascontiguousarray(raw, dtype=np.uint8)),
    ]
    return pa.RecordBatch.from_arrays(arrays, schema=schema)


def items_to_batch(items: Sequence[tuple[int, float, Frame, int]]) -> pa.RecordBatch:
    """The hub's ``(seq, received_at, frame, t2o_sequence)`` items as one record batch."""
    raw = frames_to_raw(item[2] for item in items)
    return raw_to_batch(
        [item[0] for item in items],
        [item[1] for item in items],
        raw,
        [item[3] for item in items],
    )


def conform(table: pa.Table, columns: Sequence[str]) -> pa.Table:
    """``columns`` of ``table``, in that order. A column the table lacks (a segment or journal
    written before the column existed: ``t2o_sequence``) comes back as nulls of its type, so
    an upgrade never makes older recordings unreadable."""
    names = table.schema.names
    if all(c in names for c in columns):
        return table.select(list(columns))
    arrays = [
        table.column(c) if c in names else pa.nulls(table.num_rows, SCHEMA.field(c).type)
        for c in columns
    ]
    return pa.Table.from_arrays(arrays, schema=pa.schema([SCHEMA.field(c) for c in columns]))


def raw_from_columns(table: pa.Table | pa.RecordBatch) -> U8:
    """The ``(n, 284)`` wire bytes of a table with element columns, named as the recording
    names them (``joint_position.0``) or as an export does (``joint_position.J1``); missing
    ones are 0."""
    n = table.num_rows
    raw = np.zeros((n, T2O_SIZE), dtype=np.uint8)
    names = set(table.schema.names)
    for e in ELEMENTS:
        if e.name in names:
            column = table.column(e.name)
        elif e.export_name in names:
            column = table.column(e.export_name)
        else:
            continue
        values = column.to_numpy(zero_copy_only=False)
        f = e.field
        if f.cip_type is CipType.REAL:
            raw[:, e.byte_offset : e.byte_offset + 4] = (
                np.asarray(values, dtype="<f4").view(np.uint8).reshape(n, 4)
            )
        elif f.cip_type is CipType.USINT:
            raw[:, e.byte_offset] = np.asarray(values, dtype=np.uint8)
        else:
            bit = (np.asarray(values).astype(np.uint8) & 1) << (e.bit & 7)
            raw[:, e.bit >> 3] |= bit.astype(np.uint8)
    return raw


def time_seconds(table: pa.Table | pa.RecordBatch) -> npt.NDArray[np.float64]:
    """The ``time`` column as epoch seconds (float64)."""
    column = table.column(TIME)
    micros = column.cast(pa.int64()).to_numpy(zero_copy_only=False)
    return np.asarray(micros, dtype=np.float64) / 1e6
