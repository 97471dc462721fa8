"""Layer: history storage. Imports only the layout, the history schema and query, pyarrow and
mcap.

A range of a robot's recording as a file for the tools engineers use, produced as a stream of
byte chunks (one segment at a time: memory does not grow with the range):

Every format names an element as the screen labels it (``schema.Element.export_name``:
``joint_position.J1`` is J 1's position, ``controlbox_do.DO3`` is DO 3):

- ``csv``: the receive time in ISO 8601 (``2026-11-24T06:00:00.123456Z`` in UTC; in another zone,
  the plant's as the service's ``time_zone`` names it, with its offset:
  ``2026-11-24T07:00:00.123456+01:00``), ``seq``,
  ``t2o_sequence`` (empty in rows recorded before it existed), then one column per element, its
  unit in the header (``joint_position.J1 [degree]``); pyarrow's writer quotes the header's
  names and the times (strings), not the numbers and bits; opens in Excel and pandas.
- ``parquet``: the recording's columns (``schema``: ``time`` as ``timestamp[us, UTC]``,
  ``seq``, ``t2o_sequence``, ``joint_position.J1`` …, each with its ``unit``, ``description``,
  ``label`` (``J 1``) and ``key`` (the API's element key, ``joint_position.0``) as field
  metadata); pyarrow, DuckDB, pandas and PlotJuggler read it.
- ``mcap``: a channel ``/ROBOT/frames`` of JSON messages (each frame's fields as the API's
  frame JSON has them, plus ``time``, ``seq`` and ``t2o_sequence``) with a JSON Schema, so
  Foxglove and Lichtblick plot every field without configuration; each message's MCAP
  ``sequence`` is the frame's T→O wire sequence number (the service's counter modulo 2³² in
  rows recorded before the wire number was); a channel ``/ROBOT/events`` of the robot's events
  (connection, robot state, flags, writes, control, recording, alarms) on the same time axis.
  A field asked for in part is exported whole (the message keeps the frame's shape); a
  metadata record ``cobot_hmi.columns`` names each element as the other formats do, with
  where it is in a message and its unit (``joint_position.J1`` → ``joint_position[0] [degree]``).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Final, Literal

import numpy as np
import orjson
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq
from mcap.writer import CompressionType, Writer

from cobot_hmi.history.query import iter_raw
from cobot_hmi.history.schema import ELEMENTS, SCHEMA, SEQ, T2O_SEQUENCE, TIME, Element
from cobot_hmi.history.times import compact_iso
from cobot_hmi.layout import T2O_ASSEMBLY, Field

ExportFormat = Literal["csv", "parquet", "mcap"]
FORMATS: Final = ("csv", "parquet", "mcap")
MEDIA_TYPES: Final = {
    "csv": "text/csv; charset=utf-8",
    "parquet": "application/vnd.apache.parquet",
    "mcap": "application/octet-stream",
}
CHUNK_ROWS: Final = 20_000
FRAME_SCHEMA_NAME: Final = "cobot_hmi.RobotFrame"
EVENT_SCHEMA_NAME: Final = "cobot_hmi.Event"


def export_filename(robot: str, from_s: float, to_s: float, fmt: str) -> str:
    """``ROBOT_20261124T060000Z_20261124T070000Z.csv``"""
    return f"{robot}_{compact_iso(from_s)}_{compact_iso(to_s)}.{fmt}"


class _Sink:
    """A write-only stream that keeps what is written until taken (chunks of the answer)."""

    def __init__(self) -> None:
        self._parts: list[bytes] = []
        self._position = 0
        self.closed = False

    def write(self, data: bytes | bytearray | memoryview) -> int:
        chunk = bytes(data)
        self._parts.append(chunk)
        self._position += len(chunk)
        return len(chunk)

    def tell(self) -> int:
        return self._position

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self.closed = True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return False

    def take(self) -> bytes:
        data = b"".join(self._parts)
        self._parts.clear()
        return data


def _chunks(tables_: Iterable[pa.Table], rows: int = CHUNK_ROWS) -> Iterator[pa.Table]:
    for table in tables_:
        for offset in range(0, table.num_rows, rows):
            yield table.slice(offset, rows)


def export(
    tables_: Iterable[pa.Table],
    robot: str,
    elements: Sequence[Element],
    fmt: str,
    events: Iterable[Mapping[str, object]] = (),
    *,
    zone: str = "UTC",
) -> Iterator[bytes]:
    """The export's bytes, chunk by chunk, from ``tables_`` as ``tables`` gives them; MCAP
    also ``events``, in time order (read as the frames pass them, one at a time). ``zone``
    (an IANA name): the CSV's times are written in it."""
    if fmt == "csv":
        return _csv(tables_, elements, zone)
    if fmt == "parquet":
        return _parquet(tables_, robot, elements)
    if fmt == "mcap":
        return _mcap(tables_, robot, elements, events)
    raise ValueError(f"unknown export format {fmt!r}: expected one of {', '.join(FORMATS)}")


def tables(
    root: Path, robot: str, elements: Sequence[Element], *, from_s: float, to_s: float, fmt: str
) -> Iterator[pa.Table]:
    """The tables an export of ``fmt`` reads (MCAP: whole fields)."""
    columns = [TIME, SEQ, T2O_SEQUENCE, *(e.name for e in export_elements(elements, fmt))]
    return iter_raw(root, robot, columns, from_s, to_s)


def export_elements(elements: Sequence[Element], fmt: str) -> list[Element]:
    """The elements an export holds: MCAP widens a field asked for in part to the whole."""
    if fmt != "mcap":
        return list(elements)
    fields = {e.field.name for e in elements}
    return [e for e in ELEMENTS if e.field.name in fields]


# --------------------------------------------------------------------------- CSV


def csv_header(element: Element) -> str:
    """``joint_position.J1 [degree]``; a column without a unit is its name alone."""
    name = element.export_name
    return f"{name} [{element.unit}]" if element.unit else name


_UTC_NAMES: Final = frozenset({"UTC", "Etc/UTC", "Etc/UCT", "UCT", "Zulu", "Etc/Zulu"})


def iso_times(times: pa.ChunkedArray | pa.Array, zone: str) -> pa.ChunkedArray | pa.Array:
    """Receive times as ISO 8601 text in ``zone``: ``…Z`` in UTC, else with the zone's offset
    at each moment (``+01:00`` in winter, ``+02:00`` in summer for Europe/Berlin)."""
    if zone in _UTC_NAMES:
        return pc.strftime(times, format="%Y-%m-%dT%H:%M:%SZ")
    local = pc.strftime(times.cast(pa.timestamp("us", tz=zone)), format="%Y-%m-%dT%H:%M:%S%z")
    return pc.replace_substring_regex(local, pattern=r"([+-]\d\d)(\d\d)$", replacement=r"\1:\2")


def _csv(tables_: Iterable[pa.Table], elements: Sequence[Element], zone: str) -> Iterator[bytes]:
    names = ["time", SEQ, T2O_SEQUENCE, *(csv_header(e) for e in elements)]
    types = [pa.string(), pa.int64(), pa.uint32(), *(e.arrow_type for e in elements)]
    schema = pa.schema(list(zip(names, types, strict=True)))
    sink = _Sink()
    writer = pa_csv.CSVWriter(pa.PythonFile(sink, mode="w"), schema)
    try:
        # The header even for an empty range.
        writer.write_table(schema.empty_table())
        yield sink.take()
        for table in _chunks(tables_):
            times = iso_times(table.column(TIME), zone)
            arrays = [
                times,
                table.column(SEQ),
                table.column(T2O_SEQUENCE),
                *(table.column(e.name) for e in elements),
            ]
            writer.write_table(pa.Table.from_arrays(arrays, schema=schema))
            yield sink.take()
    finally:
        writer.close()
    yield sink.take()


# --------------------------------------------------------------------------- Parquet


def _export_field(element: Element) -> pa.Field:
    """The recording's column, named as exports name it, its API key in the metadata."""
    recorded = SCHEMA.field(element.name)
    metadata = {**(recorded.metadata or {}), b"key": element.name.encode()}
    return recorded.with_name(element.export_name).with_metadata(metadata)


def export_schema(robot: str, elements: Sequence[Element]) -> pa.Schema:
    fields = [
        SCHEMA.field(TIME),
        SCHEMA.field(SEQ),
        SCHEMA.field(T2O_SEQUENCE),
        *(_export_field(e) for e in elements),
    ]
    return pa.schema(fields, metadata={"robot": robot, "layout": T2O_ASSEMBLY.name})


def _parquet(
    tables_: Iterable[pa.Table], robot: str, elements: Sequence[Element]
) -> Iterator[bytes]:
    schema = export_schema(robot, elements)
    recorded = [TIME, SEQ, T2O_SEQUENCE, *(e.name for e in elements)]
    sink = _Sink()
    writer = pq.ParquetWriter(pa.PythonFile(sink, mode="w"), schema, compression="zstd")
    try:
        for table in tables_:
            if table.num_rows:
                named = table.select(recorded).rename_columns(schema.names)
                writer.write_table(named.cast(schema))
                yield sink.take()
    finally:
        writer.close()
    yield sink.take()


# --------------------------------------------------------------------------- MCAP


def _json_type(f: Field) -> dict[str, object]:
    kind = f.value_kind
    return {"type": "number" if kind == "float" else "integer" if kind == "int" else "boolean"}


def frame_json_schema(elements: Sequence[Element]) -> dict[str, object]:
    """The JSON Schema of the ``/ROBOT/frames`` messages (whole fields of ``elements``)."""
    properties: dict[str, object] = {
        "time": {"type": "number", "description": "receive time, s since the epoch"},
        "seq": {"type": "integer", "description": "the service's frame counter of the robot"},
        T2O_SEQUENCE: {
            "type": ["integer", "null"],
            "minimum": 0,
            "maximum": 0xFFFFFFFF,
            "description": "the T→O packet's encapsulation sequence number on the wire (null: "
            "recorded before the service kept it)",
        },
    }
    seen: list[Field] = []
    for e in elements:
        if e.field not in seen:
            seen.append(e.field)
    for f in seen:
        unit = f" [{f.unit}]" if f.unit else ""
        description = f.description + unit
        if f.scalar:
            properties[f.name] = {**_json_type(f), "description": description}
        elif f.element_names:
            properties[f.name] = {
                "type": "object",
                "properties": {n: _json_type(f) for n in f.element_names},
                "required": list(f.element_names),
                "description": description,
            }
        else:
            properties[f.name] = {
                "type": "array",
                "items": _json_type(f),
                "minItems": f.count,
                "maxItems": f.count,
                "description": description + (f" ({', '.join(f.channels)})" if f.channels else ""),
            }
    return {
        "title": FRAME_SCHEMA_NAME,
        "description": T2O_ASSEMBLY.description,
        "type": "object",
        "properties": properties,
        "required": list(properties),
    }


EVENT_JSON_SCHEMA: Final = {
    "title": EVENT_SCHEMA_NAME,
    "description": "an event of the robot's event log (docs/api.md, Events)",
    "type": "object",
    "properties": {
        "kind": {"type": "string"},
        "time": {"type": "number", "description": "s since the epoch"},
        "robot": {"type": ["string", "null"]},
    },
    "required": ["kind", "time"],
    "additionalProperties": True,
}


COLUMNS_METADATA: Final = "cobot_hmi.columns"
"""The MCAP metadata record naming each exported element as the CSV and Parquet do."""


def mcap_columns(elements: Sequence[Element]) -> dict[str, str]:
    """``{"joint_position.J1": "joint_position[0] [degree]", "robot_state": "robot_state",
    "controller_version.major": "controller_version.major"}``: each element's export name →
    where a ``/ROBOT/frames`` message holds it, and its unit."""
    out: dict[str, str] = {}
    for e in elements:
        f = e.field
        if f.scalar:
            path = f.name
        elif f.element_names:
            path = f"{f.name}.{f.element_names[e.index]}"
        else:
            path = f"{f.name}[{e.index}]"
        out[e.export_name] = f"{path} [{e.unit}]" if e.unit else path
    return out


def _event_time_ns(event: Mapping[str, object]) -> int:
    t = event.get("time")
    return int(float(t) * 1e9) if isinstance(t, int | float) else 0


def _mcap(
    tables_: Iterable[pa.Table],
    robot: str,
    elements: Sequence[Element],
    events: Iterable[Mapping[str, object]],
) -> Iterator[bytes]:
    elements = export_elements(elements, "mcap")
    sink = _Sink()
    writer = Writer(sink, compression=CompressionType.ZSTD)  # type: ignore[arg-type]
    writer.start(profile="", library="cobot-hmi")
    frame_schema = writer.register_schema(
        name=FRAME_SCHEMA_NAME,
        encoding="jsonschema",
        data=json.dumps(frame_json_schema(elements)).encode(),
    )
    event_schema = writer.register_schema(
        name=EVENT_SCHEMA_NAME, encoding="jsonschema", data=json.dumps(EVENT_JSON_SCHEMA).encode()
    )
    frames = writer.register_channel(f"/{robot}/frames", "json", frame_schema)
    feed = _EventFeed(
        writer, writer.register_channel(f"/{robot}/events", "json", event_schema), events
    )
    writer.add_metadata(COLUMNS_METADATA, mcap_columns(elements))
    fields = _field_columns(elements)
    yield sink.take()
    for table in _chunks(tables_):
        for time_ns, data, sequence in _frame_messages(table, elements, fields):
            feed.until(time_ns)
            writer.add_message(frames, time_ns, data, time_ns, sequence)
        yield sink.take()
    feed.until(None)
    writer.finish()  # type: ignore[no-untyped-call]
    yield sink.take()


class _EventFeed:
    """The events (in time order, as the service's reader streams them) written to their
    channel as the frames pass their times: one event held at a time."""

    def __init__(self, writer: Writer, channel: int, events: Iterable[Mapping[str, object]]):
        self._writer = writer
        self._channel = channel
        self._pending = iter(events)
        self._upcoming = next(self._pending, None)

    def until(self, time_ns: int | None) -> None:
        """Write every event up to ``time_ns`` (``None``: all that are left)."""
        while self._upcoming is not None:
            event_ns = _event_time_ns(self._upcoming)
            if time_ns is not None and event_ns > time_ns:
                return
            data = orjson.dumps(self._upcoming, option=orjson.OPT_NON_STR_KEYS)
            self._writer.add_message(self._channel, event_ns, data, event_ns)
            self._upcoming = next(self._pending, None)


def _field_columns(elements: Sequence[Element]) -> list[tuple[Field, list[str]]]:
    """The elements grouped by their field, in order: each field and its columns."""
    fields: list[tuple[Field, list[str]]] = []
    for e in elements:
        if not fields or fields[-1][0] is not e.field:
            fields.append((e.field, []))
        fields[-1][1].append(e.name)
    return fields


def _frame_messages(
    table: pa.Table, elements: Sequence[Element], fields: list[tuple[Field, list[str]]]
) -> Iterator[tuple[int, bytes, int]]:
    """Each row of ``table`` as a ``/ROBOT/frames`` message: its time, ns, its JSON (the frame's
    shape, ``codec.frame_to_json``: scalars, arrays, records) and its sequence number."""
    micros = table.column(TIME).cast(pa.int64()).to_numpy()
    times_ns = (micros.astype(np.int64) * 1000).tolist()
    times_s = (micros / 1e6).tolist()
    seqs = table.column(SEQ).to_pylist()
    wire = table.column(T2O_SEQUENCE).to_pylist()
    values = {e.name: table.column(e.name).to_pylist() for e in elements if e.kind != "float"}
    # REAL arrays as float32 rows: orjson writes each as the shortest text that reads back
    # as the same float32 (as the CSV does), not the 17 digits of its double.
    blocks = {
        f.name: np.column_stack(
            [table.column(c).to_numpy(zero_copy_only=False) for c in columns]
        ).astype(np.float32)
        for f, columns in fields
        if f.value_kind == "float"
    }
    for row, time_ns in enumerate(times_ns):
        message: dict[str, object] = {
            "time": times_s[row],
            "seq": seqs[row],
            T2O_SEQUENCE: wire[row],
        }
        for f, columns in fields:
            if f.name in blocks:
                message[f.name] = blocks[f.name][row]
            elif f.scalar:
                message[f.name] = values[columns[0]][row]
            elif f.element_names:
                message[f.name] = {
                    n: values[c][row] for n, c in zip(f.element_names, columns, strict=True)
                }
            else:
                message[f.name] = [values[c][row] for c in columns]
        data = orjson.dumps(message, option=orjson.OPT_SERIALIZE_NUMPY)
        # MCAP's message sequence is a uint32, as the wire number is.
        sequence = wire[row] if wire[row] is not None else seqs[row] & 0xFFFFFFFF
        yield time_ns, data, sequence
