"""Layer: history storage. Imports only the history rollup and formats, and pyarrow.

A closed segment's cells file (``START-END.cells.arrow``, beside its Parquet, ``segments``):
the per-second cells of its frames and their coarser levels (``rollup``), an Arrow IPC file
compressed with LZ4, one record batch per cell width of ``rollup.LEVELS_S`` (1 s, 10 s, 1 min)
named in the schema's ``cell_widths_s`` metadata. A query memory-maps it and decompresses only
the columns of the one batch it reads, about 0.7 ms a file where Parquet's footer of 750
columns alone costs several, and keeps what it read (``read_cells_file``). A cells file
written before the coarser widths existed holds the per-second batch only and no metadata. A
cells file carries its format's version and the layout's (``formats``); one of a newer format
is refused by name.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Any, Final

import pyarrow as pa

from cobot_hmi.history.formats import CELLS, check_versions, version_metadata
from cobot_hmi.history.rollup import LEVELS_S, levels, rollup_schema

CELL_WIDTHS_KEY: Final = b"cell_widths_s"
"""Schema metadata of a cells file: its batches' cell widths, s, in order (``1,10,60``)."""


def write_cells(cells: pa.Table, path: Path) -> None:
    """The per-second cells and their coarser levels as an Arrow IPC file (LZ4), a record
    batch per level, fsync'd, renamed in place."""
    temporary = path.with_name(path.name + ".tmp")
    try:
        with open(temporary, "wb") as sink:
            write_cells_to(cells, sink)
            sink.flush()
            os.fsync(sink.fileno())
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise


def write_cells_to(cells: pa.Table, sink: Any) -> None:
    """``write_cells`` into an open file or stream."""
    options = pa.ipc.IpcWriteOptions(compression="lz4")
    widths = ",".join(str(w) for w in LEVELS_S).encode()
    schema = cells.schema.with_metadata({CELL_WIDTHS_KEY: widths, **version_metadata(CELLS)})
    with pa.ipc.new_file(sink, schema, options=options) as writer:
        for level in levels(cells):
            # One batch per level: the reader finds a level by its index.
            writer.write_batch(level.combine_chunks().to_batches()[0])


_CellsKey = tuple[Path, int]
"""A cells file and a cell width, s."""


class _CellsCache:
    """Columns of closed segments' cells files, per cell width, the most recently used first
    out last, up to ``max_bytes``: a closed segment's files never change. An entry is one
    table (whatever columns were read), so a query's work per file is a few calls, not one per
    column."""

    def __init__(self, max_bytes: int) -> None:
        self.max_bytes = max_bytes
        self.bytes = 0
        self._entries: OrderedDict[_CellsKey, pa.Table] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: _CellsKey) -> pa.Table | None:
        with self._lock:
            entry = self._entries.get(key)
            if entry is not None:
                self._entries.move_to_end(key)
            return entry

    def keep(self, key: _CellsKey, table: pa.Table) -> None:
        """``table`` replaces the entry (it holds the entry's columns and more)."""
        with self._lock:
            # get_total_buffer_size: a sum, where nbytes looks for shared buffers (20x slower).
            old = self._entries.pop(key, None)
            if old is not None:
                self.bytes -= old.get_total_buffer_size()
            self._entries[key] = table
            self.bytes += table.get_total_buffer_size()
            while self.bytes > self.max_bytes and len(self._entries) > 1:
                _, evicted = self._entries.popitem(last=False)
                self.bytes -= evicted.get_total_buffer_size()

    def clear(self) -> None:
        with self._lock:
            self._entries.clear()
            self.bytes = 0


_CELLS: Final = _CellsCache(128 * 1024 * 1024)
_CELLS_SCHEMA: Final = rollup_schema()
"""The cells files' columns (their order locates a column without parsing a file twice)."""


def forget_cells() -> None:
    """Empty the cells cache (a benchmark's cold query)."""
    _CELLS.clear()


def read_cells_file(path: Path, columns: list[str], width_s: int = 1) -> pa.Table | None:
    """``columns`` of a cells file's cells of ``width_s`` seconds (``OSError``/
    ``ArrowException``; ``FormatVersionError`` for a newer format); ``None`` when the file has
    no such level (written before it existed).
    The columns read are kept (``_CellsCache``, 128 MiB), so a plot that pans and zooms over
    days reads each file once."""
    key = (path, width_s)
    cached = _CELLS.get(key)
    have = set() if cached is None else set(cached.column_names)
    missing = [c for c in columns if c not in have]
    if missing:
        read = _read_cells_columns(path, missing, width_s)
        if read is None:
            return None
        if cached is not None:
            read = pa.Table.from_arrays(
                [*cached.columns, *read.columns], names=[*cached.column_names, *read.column_names]
            )
        _CELLS.keep(key, read)
        cached = read
    assert cached is not None
    # By position: selecting 200 columns by name searches the names 200 times.
    position = {name: i for i, name in enumerate(cached.column_names)}
    return cached.select([position[c] for c in columns])


def _read_cells_columns(path: Path, columns: list[str], width_s: int) -> pa.Table | None:
    """``columns`` (in the file's order, one chunk each) of the cells of ``width_s`` seconds."""
    with pa.memory_map(str(path)) as source:
        indices = [_CELLS_SCHEMA.get_field_index(c) for c in columns]
        reader = _open_cells(source, indices)
        if reader is None or set(reader.schema.names) != set(columns):
            # Columns elsewhere than today's layout puts them: found by name.
            schema = pa.ipc.open_file(source).schema
            indices = [schema.get_field_index(c) for c in columns]
            if min(indices, default=0) < 0:
                raise pa.ArrowInvalid(f"{path}: a column is missing")
            reader = _open_cells(source, indices)
            assert reader is not None
        check_versions(CELLS, reader.schema.metadata, path)
        widths = (reader.schema.metadata or {}).get(CELL_WIDTHS_KEY)
        if widths is None:  # written before the coarser levels: per-second cells only
            if width_s != 1:
                return None
            table = reader.read_all().combine_chunks()
        else:
            order = [int(w) for w in widths.decode().split(",")]
            if width_s not in order:
                return None
            # Decompressed out of the mapping: nothing refers to it once it closes.
            table = pa.Table.from_batches([reader.get_batch(order.index(width_s))])
    return table


def _open_cells(
    source: pa.MemoryMappedFile, indices: list[int]
) -> pa.ipc.RecordBatchFileReader | None:
    if min(indices, default=0) < 0:
        return None
    options = pa.ipc.IpcReadOptions(included_fields=indices, use_threads=False)
    return pa.ipc.open_file(source, options=options)
