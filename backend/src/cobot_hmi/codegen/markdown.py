"""Layer: layout tooling. Writes ``docs/assembly.md``, the map a human reads."""

from __future__ import annotations

from collections.abc import Iterable

from cobot_hmi.codegen.common import HEADER
from cobot_hmi.layout import (
    ANALOG_OUTPUT_RANGES,
    ASSEMBLIES,
    LAYOUT_VERSION,
    ROBOT_STATES,
    T2O_ASSEMBLY,
    UNKNOWN_STATE_NAME,
    Assembly,
    CipType,
    Field,
)


def _bit_range(f: Field) -> str:
    if f.cip_type is not CipType.BOOL:
        return ""
    first = f.first_bit or 0
    return f"{first}" if f.count == 1 else f"{first}–{first + f.count - 1}"


def _bytes_range(start_bit: int, bit_count: int) -> str:
    first, last = start_bit // 8, (start_bit + bit_count - 1) // 8
    return f"{first}" if first == last else f"{first}–{last}"


def _reserved_ranges(assembly: Assembly) -> list[tuple[int, int]]:
    used = [False] * (assembly.size_bytes * 8)
    for f in assembly.fields:
        for bit in range(f.first_wire_bit, f.first_wire_bit + f.bit_count):
            used[bit] = True
    ranges: list[tuple[int, int]] = []
    start: int | None = None
    for bit, is_used in enumerate([*used, True]):
        if not is_used and start is None:
            start = bit
        elif start is not None and (is_used or bit % 32 == 0):
            ranges.append((start, bit - start))
            start = None if is_used else bit
    return ranges


def _assembly_md(assembly: Assembly) -> Iterable[str]:
    arrow = "T→O, robot → PLC" if assembly is T2O_ASSEMBLY else "O→T, PLC → robot"
    yield (
        f"## {assembly.name} ({arrow}): {assembly.size_bytes} bytes, "
        f"instance {assembly.default_instance} by default"
    )
    yield ""
    yield assembly.description + "."
    yield ""
    yield "| bytes | word offset | bits | CIP type | count | field | unit | description |"
    yield "|---:|---:|---|---|---:|---|---|---|"
    for f in assembly.fields:
        extra = ""
        if f.value_names:
            extra = " (" + ", ".join(f"{i} = {n}" for i, n in enumerate(f.value_names)) + ")"
        if f.flag:
            extra = f" ({f.flag.abbreviation} = {f.flag.full_name})"
        yield (
            f"| {_bytes_range(f.first_wire_bit, f.bit_count)} | {f.offset} | {_bit_range(f)} "
            f"| {f.cip_type.value} | {f.count} | `{f.name}` | {f.unit} | {f.description}{extra} |"
        )
    yield ""
    reserved = [
        f"word {start // 32 * 4} bits {start % 32}–{(start + count - 1) % 32}"
        for start, count in _reserved_ranges(assembly)
    ]
    yield "Reserved (sent as zero, ignored on receipt): " + "; ".join(reserved) + "."
    yield ""


READING_DECISIONS = (
    "## Reading decisions",
    "",
    "The robot's I/O table, as exported, lost cell positions where cells were merged. Each "
    "decision below is data in `layout.py`, so a reading found wrong against a real controller "
    "is a one-line fix that the emulator, the backend, the frontend and these docs all follow.",
    "",
    "- **Tool I/O and AO type bits.** Taken literally the export gives 4 tool inputs at bits "
    "0–3 and 4 tool outputs at bits 12–15 (its group label sits 8 columns early). The robot has "
    "6 tool inputs and 6 tool outputs (Doosan's Modbus table: tool DI 1–6, tool DO 1–6), and the "
    "only reading that puts every label of both rows in a consistent place is: tool DI at bits "
    "0–5 and tool DO at bits 16–21 of T→O word 24; tool DO at bits 16–21 and AO type at bits "
    "24–25 of O→T word 0.",
    "- **Patch version.** Taken literally 4 bits wide (16–19); the same shift explains it, and an "
    "8-bit field is read.",
    "- **Flag order.** Doosan's Modbus table orders the flags SO, ES, SS, DTBP, PBP; the robot's "
    "I/O table says SO, SS, ES, which is followed.",
    "- **State enum.** Doosan's programming API has an older `ROBOT_STATE` enum (0–15); the I/O "
    "table's numbering (above) is followed.",
    "- **Longer frames.** A controller can be configured to send more than 284 bytes (general "
    "purpose registers after the monitoring block). A decoder accepts a longer T→O frame, decodes "
    "the first 284 bytes and keeps the rest as raw bytes (`extra`), and rejects a shorter one "
    "with a clear error.",
    "",
)
"""The reading decisions behind the layout, printed at the end of docs/assembly.md."""


def assembly_doc() -> str:
    lines = [
        f"<!-- {HEADER} -->",
        "",
        "# Assembly map",
        "",
        f"Layout version {LAYOUT_VERSION}. Little-endian; `REAL` is IEEE-754 binary32; bit *n* "
        "of the word at byte offset *o* is bit *n mod 8* of byte *o + n div 8*. JSON keys of "
        "arrays are 0-based indexes; channels are labelled as the robot labels them.",
        "",
        "The table itself lives in `backend/src/cobot_hmi/layout.py`; the reading decisions "
        "behind it are at the end of this page.",
        "",
        "Connection sizes on the wire (protocol notes): O→T data + 2 (CIP sequence count) "
        "+ 4 (run/idle header); T→O data + 2.",
        "",
    ]
    for assembly in ASSEMBLIES:
        lines += list(_assembly_md(assembly))
    lines += [
        "## Robot state (T→O byte 32)",
        "",
        "| value | name | in plain words | pendant colour | description |",
        "|---:|---|---|---|---|",
    ]
    for s in ROBOT_STATES:
        colours = " and ".join(s.pendant_colours) + ("" if s.colour_from_table else " (assumed)")
        lines.append(f"| {s.value} | `{s.name}` | {s.label} | {colours} | {s.description} |")
    lines += [
        f"| other | `{UNKNOWN_STATE_NAME}` | Unknown state | grey | Not in the table: shown as "
        "such, never an error. |",
        "",
        "Colours marked *assumed* are not stated by the robot's table; they follow the severity "
        "of the state and are a setting to check against a real teach pendant.",
        "",
        "## Analog output ranges",
        "",
        "| type | low | high | unit |",
        "|---|---:|---:|---|",
    ]
    for coding, (low, high, unit) in ANALOG_OUTPUT_RANGES.items():
        lines.append(f"| {coding} | {low:g} | {high:g} | {unit} |")
    lines += ["", *READING_DECISIONS]
    return "\n".join(lines)
