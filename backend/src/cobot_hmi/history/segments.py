"""Layer: history storage. Imports only the history schema and rollup, and pyarrow.

A robot's recording is a directory of segments (``HISTORY_DIR/ROBOT/``):

- the open segment, a *journal*: ``START.journal.arrows``, an Arrow IPC stream to which the
  recorder appends one record batch per flush (every ``flush_s``, default 1 s). Each batch is
  written whole with one ``write`` before the next is taken, so a ``kill -9`` of the service
  leaves every flushed batch readable (the operating system holds the page cache) and at
  most a torn last batch, which the
  reader skips. What a crash can lose is the batch not yet flushed: at most ``flush_s`` of
  frames plus the recorder's queue, within the 2 s bound. The journal is fsync'd every
  ``JOURNAL_SYNC_S`` (10 s), which bounds what a power cut takes.
- closed segments: ``START-END.parquet`` (the frames, zstd, one row group per 64 Ki rows) and
  ``START-END.cells.arrow`` (the cells, ``rollup``: an Arrow IPC file compressed with LZ4, one
  record batch per cell width of ``rollup.LEVELS_S``, 1 s, 10 s and 1 min, named in the
  schema's ``cell_widths_s`` metadata; a query memory-maps it and decompresses only the
  columns of the one batch it reads, about 0.7 ms a file where Parquet's footer of 750 columns
  alone costs several). A cells file written before the coarser widths existed holds the
  per-second batch only and no metadata; a query then coarsens those. Both are written to a
  temporary name, fsync'd, renamed into place and the directory fsync'd, cells first: a ``.parquet``
  exists only complete. Then the journal goes.

``START``/``END`` are the first and last frame's receive times in epoch microseconds, so a
query picks its segments from the names alone. On start, ``recover`` closes every journal left
by a crash (its complete batches), and recording resumes in a new journal.
"""

from __future__ import annotations

import contextlib
import os
import re
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import pyarrow as pa
import pyarrow.parquet as pq

from cobot_hmi.history.rollup import LEVELS_S, levels, rollup_schema, rollup_table
from cobot_hmi.history.schema import ELEMENTS, SCHEMA, SEQ, T2O_SEQUENCE, TIME, conform

JOURNAL_SUFFIX: Final = ".journal.arrows"
ROLLUP_SUFFIX: Final = ".cells.arrow"
SEGMENT_SUFFIX: Final = ".parquet"
ROW_GROUP_ROWS: Final = 64 * 1024
JOURNAL_SYNC_S: Final = 10.0
"""The open segment's journal is fsync'd this often (a power cut loses at most this much)."""
_FLOATS: Final = [e.name for e in ELEMENTS if e.kind == "float"]
_ENCODINGS: Final = {
    **dict.fromkeys(_FLOATS, "BYTE_STREAM_SPLIT"),
    TIME: "DELTA_BINARY_PACKED",
    SEQ: "DELTA_BINARY_PACKED",
    T2O_SEQUENCE: "DELTA_BINARY_PACKED",
}
"""Floats split into byte streams (zstd then finds the slowly changing exponent bytes), times
and counters as deltas: 12 % smaller than the defaults and three times faster to write (a day
of the simulated robot, bench/history)."""
_DICTIONARY_COLUMNS: Final = [name for name in SCHEMA.names if name not in _ENCODINGS]
_SEGMENT_NAME: Final = re.compile(r"^(\d+)-(\d+)\.parquet$")
_JOURNAL_NAME: Final = re.compile(r"^(\d+)\.journal\.arrows$")
CELL_WIDTHS_KEY: Final = b"cell_widths_s"
"""Schema metadata of a cells file: its batches' cell widths, s, in order (``1,10,60``)."""


@dataclass(frozen=True, slots=True)
class Segment:
    """A closed segment: its frames, its cells and the receive times it spans."""

    robot: str
    path: Path
    start_us: int
    end_us: int

    @property
    def rollup_path(self) -> Path:
        return self.path.with_name(self.path.name[: -len(SEGMENT_SUFFIX)] + ROLLUP_SUFFIX)

    def size_bytes(self) -> int:
        total = 0
        for path in (self.path, self.rollup_path):
            with contextlib.suppress(OSError):
                total += path.stat().st_size
        return total


def robot_dir(root: Path, robot: str) -> Path:
    return root / robot


def list_robots(root: Path) -> list[str]:
    """Robots with a directory under ``root`` (recorded at some time)."""
    try:
        return sorted(p.name for p in root.iterdir() if p.is_dir())
    except OSError:
        return []


def list_segments(root: Path, robot: str) -> list[Segment]:
    """The robot's closed segments, oldest first."""
    out = []
    try:
        entries = list(os.scandir(robot_dir(root, robot)))
    except OSError:
        return []
    for entry in entries:
        match = _SEGMENT_NAME.match(entry.name)
        if match:
            out.append(Segment(robot, Path(entry.path), int(match[1]), int(match[2])))
    out.sort(key=lambda s: (s.start_us, s.end_us))
    return out


def list_journals(root: Path, robot: str) -> list[tuple[int, Path]]:
    """The robot's journals (the open segment; more than one only after a crash)."""
    out = []
    try:
        entries = list(os.scandir(robot_dir(root, robot)))
    except OSError:
        return []
    for entry in entries:
        match = _JOURNAL_NAME.match(entry.name)
        if match:
            out.append((int(match[1]), Path(entry.path)))
    out.sort()
    return out


class _Journal:
    """What a reader has parsed of one journal: the batches up to ``offset`` bytes."""

    __slots__ = ("batches", "identity", "offset", "schema")

    def __init__(self, identity: tuple[int, int]) -> None:
        self.identity = identity
        self.offset = 0
        self.schema: pa.Schema | None = None
        self.batches: list[pa.RecordBatch] = []


_JOURNALS: Final[OrderedDict[Path, _Journal]] = OrderedDict()
_JOURNALS_LOCK: Final = threading.Lock()
_JOURNALS_KEPT: Final = 16
_CONSOLIDATE_BATCHES: Final = 128


def read_journal(path: Path, columns: Sequence[str] | None = None) -> pa.Table:
    """Every complete batch of a journal (a torn last batch, from a crash, is left out),
    ``columns`` only (default: every column of the recording's schema; one a journal written
    before it existed lacks comes back as nulls, ``schema.conform``).

    A journal only grows, a batch a second: the batches parsed are kept per journal (the last
    few journals read), so a query of the open segment parses only the new ones; parsing all
    of a ten-minute journal (600 batches of 190 columns) costs about 100 ms, the new second a
    fraction of a millisecond."""
    batches, schema = _journal_batches(path)
    if not batches or schema is None:
        return _empty(columns)
    table = pa.Table.from_batches(batches, schema=schema)
    table = conform(table, SCHEMA.names if columns is None else columns)
    return table.combine_chunks()


def _journal_batches(path: Path) -> tuple[list[pa.RecordBatch], pa.Schema | None]:
    try:
        stat = os.stat(path)
    except OSError:
        forget_journal(path)
        return [], None
    identity = (stat.st_dev, stat.st_ino)
    with _JOURNALS_LOCK:
        entry = _JOURNALS.get(path)
        if entry is None or entry.identity != identity or stat.st_size < entry.offset:
            entry = _Journal(identity)
        _JOURNALS[path] = entry
        _JOURNALS.move_to_end(path)
        while len(_JOURNALS) > _JOURNALS_KEPT:
            _JOURNALS.popitem(last=False)
        if stat.st_size > entry.offset:
            with contextlib.suppress(OSError):  # read again next time
                _parse_more(path, entry, stat.st_size)
        return list(entry.batches), entry.schema


def _parse_more(path: Path, entry: _Journal, size: int) -> None:
    """Parse the complete IPC messages between ``entry.offset`` and ``size``."""
    with path.open("rb") as file:
        file.seek(entry.offset)
        data = file.read(size - entry.offset)
    reader = pa.BufferReader(pa.py_buffer(data))
    consumed = 0
    while True:
        try:
            message = pa.ipc.read_message(reader)
        except (EOFError, OSError, pa.ArrowException):  # the end, or a batch still torn
            break
        if message is None:
            break
        try:
            if entry.schema is None:
                entry.schema = pa.ipc.read_schema(message)
            else:
                entry.batches.append(pa.ipc.read_record_batch(message, entry.schema))
        except (OSError, pa.ArrowException):
            break
        consumed = reader.tell()
    entry.offset += consumed
    if len(entry.batches) > _CONSOLIDATE_BATCHES and entry.schema is not None:
        # One batch instead of many: a query's concatenation stays cheap.
        whole = pa.Table.from_batches(entry.batches, schema=entry.schema).combine_chunks()
        entry.batches = whole.to_batches()


def forget_journal(path: Path) -> None:
    """Drop what was parsed of a journal (it was closed into a segment)."""
    with _JOURNALS_LOCK:
        _JOURNALS.pop(path, None)


def _empty(columns: Sequence[str] | None) -> pa.Table:
    table = SCHEMA.empty_table()
    return table if columns is None else table.select(list(columns))


def _fsync_dir(directory: Path) -> None:
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _write_parquet(table: pa.Table, path: Path, row_group_rows: int) -> None:
    """Without the Arrow schema in the footer (the columns' types read back the same; the
    units and descriptions would add kilobytes to every segment), fsync'd, renamed in place."""
    temporary = path.with_name(path.name + ".tmp")
    try:
        with open(temporary, "wb") as sink:
            pq.write_table(
                table,
                sink,
                compression="zstd",
                row_group_size=row_group_rows,
                write_statistics=True,
                store_schema=False,
                use_dictionary=_DICTIONARY_COLUMNS,
                column_encoding=_ENCODINGS,
            )
            sink.flush()
            os.fsync(sink.fileno())
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise


def _write_cells(cells: pa.Table, path: Path) -> None:
    """The per-second cells and their coarser levels as an Arrow IPC file (LZ4), a record
    batch per level, fsync'd, renamed in place."""
    temporary = path.with_name(path.name + ".tmp")
    options = pa.ipc.IpcWriteOptions(compression="lz4")
    widths = ",".join(str(w) for w in LEVELS_S).encode()
    schema = cells.schema.with_metadata({CELL_WIDTHS_KEY: widths})
    try:
        with open(temporary, "wb") as sink:
            with pa.ipc.new_file(sink, schema, options=options) as writer:
                for level in levels(cells):
                    # One batch per level: the reader finds a level by its index.
                    writer.write_batch(level.combine_chunks().to_batches()[0])
            sink.flush()
            os.fsync(sink.fileno())
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise


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
    ``ArrowException``); ``None`` when the file has no such level (written before it existed).
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


def write_segment(table: pa.Table, directory: Path, robot: str) -> Segment | None:
    """Write ``table`` (sorted by time) as a closed segment; ``None`` for an empty table."""
    if table.num_rows == 0:
        return None
    micros = table.column(TIME).cast(pa.int64())
    start_us, end_us = int(micros[0].as_py()), int(micros[-1].as_py())
    segment = Segment(robot, directory / f"{start_us}-{end_us}{SEGMENT_SUFFIX}", start_us, end_us)
    _write_cells(rollup_table(table), segment.rollup_path)
    _write_parquet(table, segment.path, ROW_GROUP_ROWS)
    _fsync_dir(directory)
    return segment


def close_journal(path: Path, robot: str) -> Segment | None:
    """Turn a journal into a closed segment and delete it (also after a crash)."""
    forget_journal(path)
    table = read_journal(path)
    forget_journal(path)
    segment = write_segment(table, path.parent, robot) if table.num_rows else None
    path.unlink(missing_ok=True)
    return segment


def recover(root: Path, robot: str) -> list[Segment]:
    """Close every journal a crash left behind; the closed segments made."""
    made = []
    for _, path in list_journals(root, robot):
        segment = close_journal(path, robot)
        if segment is not None:
            made.append(segment)
    return made


class SegmentWriter:
    """The open segment of one robot: append batches, close it every ``segment_s``.

    Not thread-safe: one owner (the recorder's thread). ``OSError`` (disk full, read-only,
    removed directory) propagates: the caller pauses; the journal written so far stays valid.
    """

    def __init__(
        self,
        root: Path,
        robot: str,
        segment_s: float,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.root = root
        self.robot = robot
        self.segment_s = segment_s
        self._clock = clock
        self._path: Path | None = None
        self._sink: pa.OSFile | None = None
        self._writer: pa.ipc.RecordBatchStreamWriter | None = None
        self._opened_at = 0.0
        self._synced_at = 0.0
        self.rows = 0
        """Rows in the open segment."""

    @property
    def journal_path(self) -> Path | None:
        return self._path

    def append(self, batch: pa.RecordBatch) -> None:
        """Write one batch to the journal (opened with the first batch of a segment)."""
        if batch.num_rows == 0:
            return
        if self._writer is None:
            self._open(batch)
        assert self._writer is not None
        self._writer.write_batch(batch)
        self.rows += batch.num_rows
        now = self._clock()
        if now - self._synced_at >= JOURNAL_SYNC_S and self._path is not None:
            # The page cache survives kill -9 already; this bounds what a power cut takes.
            fd = os.open(self._path, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            self._synced_at = now

    def _open(self, batch: pa.RecordBatch) -> None:
        directory = robot_dir(self.root, self.robot)
        directory.mkdir(parents=True, exist_ok=True)
        start_us = int(batch.column(TIME).cast(pa.int64())[0].as_py())
        path = directory / f"{start_us}{JOURNAL_SUFFIX}"
        sink = pa.OSFile(str(path), "wb")
        try:
            writer = pa.ipc.new_stream(sink, SCHEMA)
        except BaseException:
            sink.close()
            raise
        self._path, self._sink, self._writer = path, sink, writer
        self._opened_at = self._synced_at = self._clock()
        self.rows = 0

    def due(self) -> bool:
        """The open segment has lasted ``segment_s``."""
        return self._writer is not None and self._clock() - self._opened_at >= self.segment_s

    def close_segment(self) -> Segment | None:
        """Close the journal and turn it into a closed segment (``None``: nothing open)."""
        path = self._path
        if path is None:
            return None
        self._abandon()
        return close_journal(path, self.robot)

    def _abandon(self) -> None:
        """Close the journal's file without compacting it (after a write error: it stays on
        disk for ``recover``)."""
        writer, sink = self._writer, self._sink
        self._path, self._sink, self._writer = None, None, None
        self.rows = 0
        if writer is not None:
            with contextlib.suppress(OSError, pa.ArrowException):
                writer.close()
        if sink is not None:
            with contextlib.suppress(OSError, pa.ArrowException):
                sink.close()

    def abandon(self) -> None:
        self._abandon()
