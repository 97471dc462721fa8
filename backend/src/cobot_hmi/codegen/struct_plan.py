"""Layer: layout tooling. How an assembly is cut into ``struct`` items.

Every byte that holds bits is its own ``B`` item, so that a whole byte of bits decodes with one
table look-up and no shifting; REAL and USINT fields are runs. Reserved bytes are pad bytes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cobot_hmi.layout import Assembly, CipType, Field


@dataclass
class Slot:
    """One ``struct`` item run: a byte that holds bits, or a REAL / USINT run of ``items``."""

    start: int
    size: int
    code: str
    items: int
    fields: list[Field] = field(default_factory=list)


@dataclass(frozen=True)
class BitChunk:
    """The part of a BOOL field that lies in one byte: ``width`` bits from bit ``shift``."""

    byte: int
    shift: int
    first_element: int
    width: int


def bit_chunks(f: Field) -> list[BitChunk]:
    chunks = []
    position, element = f.first_wire_bit, 0
    while element < f.count:
        shift = position % 8
        width = min(8 - shift, f.count - element)
        chunks.append(BitChunk(position // 8, shift, element, width))
        position += width
        element += width
    return chunks


def slots(assembly: Assembly) -> list[Slot]:
    """Cut an assembly into struct items: every byte holding bits is its own ``B`` item, so
    that a whole byte of bits decodes with one table look-up and no shifting; REAL and USINT
    fields are runs."""
    slots: list[Slot] = []
    bit_bytes: dict[int, list[Field]] = {}
    for f in assembly.fields:
        if f.cip_type is CipType.BOOL:
            for chunk in bit_chunks(f):
                bit_bytes.setdefault(chunk.byte, []).append(f)
        else:
            code = "f" if f.cip_type is CipType.REAL else "B"
            size = {"f": 4, "B": 1}[code]
            slots.append(Slot(f.offset, size * f.count, f"{f.count}{code}", f.count, [f]))
    slots += [Slot(byte, 1, "B", 1, fields) for byte, fields in bit_bytes.items()]
    slots.sort(key=lambda s: s.start)
    return slots


def struct_format(assembly: Assembly) -> str:
    """The little-endian ``struct`` format covering the whole assembly, pads for reserved bytes."""
    parts = ["<"]
    position = 0
    for slot in slots(assembly):
        if slot.start < position:
            raise ValueError(f"{assembly.name}: overlapping items at byte {slot.start}")
        if slot.start > position:
            parts.append(f"{slot.start - position}x")
        parts.append(slot.code)
        position = slot.start + slot.size
    if position > assembly.size_bytes:
        raise ValueError(f"{assembly.name}: items run past {assembly.size_bytes} bytes")
    if position < assembly.size_bytes:
        parts.append(f"{assembly.size_bytes - position}x")
    return "".join(parts)


def item_index(assembly: Assembly) -> dict[int, int]:
    """Byte offset of each slot → index of its first value in the unpacked tuple."""
    index, positions = 0, {}
    for slot in slots(assembly):
        positions[slot.start] = index
        index += slot.items
    return positions
