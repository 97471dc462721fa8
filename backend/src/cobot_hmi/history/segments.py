"""Layer: history storage. Imports only the codec, the history schema, formats, rollup and cells,
numpy and pyarrow.

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
  ``START-END.cells.arrow`` (their cells at 1 s, 10 s and 1 min, ``cells``). A journal
  becomes a segment a row group at a time (``close_journal``): memory holds one row group, not
  the journal. Both are written to a temporary name, fsync'd, renamed into place and the
  directory fsync'd, cells first: a ``.parquet`` exists only complete. Then the journal goes.

``START``/``END`` are the first and last frame's receive times in epoch microseconds, so a
query picks its segments from the names alone. Journals and segments carry their format's
version and the layout's (``formats``); one newer than this build reads is refused by name. On
start, ``recover`` closes every journal left by a crash (its complete batches), and recording
resumes in a new journal.
"""

from __future__ import annotations

import contextlib
import os
import re
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import pyarrow as pa
import pyarrow.parquet as pq

from cobot_hmi.history.cells import write_cells
from cobot_hmi.history.formats import JOURNAL, SEGMENT, check_versions, version_metadata
from cobot_hmi.history.journal_form import expand, is_journal_form
from cobot_hmi.history.rollup import join_split_cells, rollup_table
from cobot_hmi.history.schema import (
    ELEMENTS,
    SCHEMA,
    SEQ,
    T2O_SEQUENCE,
    TIME,
    conform,
)
from cobot_hmi.stored_format import FormatVersionError

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


def open_segment(path: Path) -> pq.ParquetFile:
    """A closed segment's Parquet file, its footer read (``OSError``, ``ArrowException``); one
    of a newer format raises ``FormatVersionError``."""
    file = pq.ParquetFile(path)
    check_versions(SEGMENT, file.metadata.metadata, path)
    return file


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

    __slots__ = ("batches", "file_schema", "identity", "offset", "schema")

    def __init__(self, identity: tuple[int, int]) -> None:
        self.identity = identity
        self.offset = 0
        self.file_schema: pa.Schema | None = None
        """The journal's own schema (its form: ``journal_form``)."""
        self.schema: pa.Schema | None = None
        """The batches' schema once expanded (the recording's, for a journal of payloads)."""
        self.batches: list[pa.RecordBatch] = []


_JOURNALS: Final[OrderedDict[Path, _Journal]] = OrderedDict()
_JOURNALS_LOCK: Final = threading.Lock()
_JOURNALS_KEPT: Final = 16
_CONSOLIDATE_BATCHES: Final = 128
EXPAND_ROWS: Final = 4096
"""Rows of a journal of payloads sliced into columns at a time when it is closed."""


def read_journal(path: Path, columns: Sequence[str] | None = None) -> pa.Table:
    """Every complete batch of a journal (a torn last batch, from a crash, is left out),
    ``columns`` only (default: every column of the recording's schema; one a journal written
    before it existed lacks comes back as nulls, ``schema.conform``). A journal of a newer
    format raises ``FormatVersionError``.

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
            if entry.file_schema is None:
                file_schema = pa.ipc.read_schema(message)
                check_versions(JOURNAL, file_schema.metadata, path)  # refused: raised
                entry.file_schema = file_schema
                entry.schema = SCHEMA if is_journal_form(file_schema) else file_schema
            else:
                batch = pa.ipc.read_record_batch(message, entry.file_schema)
                entry.batches.append(expand(batch))
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


def _write_parquet(groups: Iterator[pa.Table], sink: Any) -> tuple[pa.Table, int, int] | None:
    """``groups`` (tables of one schema, ``ROW_GROUP_ROWS`` rows each but the last) as Parquet
    into ``sink``, a row group each; their per-second cells (a cell split between two groups
    is one, ``rollup.join_split_cells``) and the first and last receive time, µs; ``None`` for
    no rows. Memory holds one group at a time. Without the Arrow schema in the footer (the
    columns' types read back the same; the units and descriptions would add kilobytes to
    every segment)."""
    cells: list[pa.Table] = []
    writer: pq.ParquetWriter | None = None
    first_us = last_us = 0
    try:
        for group in groups:
            if group.num_rows == 0:
                continue
            if writer is None:
                writer = pq.ParquetWriter(
                    sink,
                    group.schema,
                    compression="zstd",
                    write_statistics=True,
                    store_schema=False,
                    use_dictionary=_DICTIONARY_COLUMNS,
                    column_encoding=_ENCODINGS,
                )
                writer.add_key_value_metadata(version_metadata(SEGMENT))
                first_us = _time_us(group, 0)
            writer.write_table(group, row_group_size=ROW_GROUP_ROWS)
            last_us = _time_us(group, -1)
            cells.append(rollup_table(group))
            del group  # before the next is read
    finally:
        if writer is not None:
            writer.close()
    if not cells:
        return None
    return join_split_cells(pa.concat_tables(cells).combine_chunks()), first_us, last_us


def _time_us(table: pa.Table, row: int) -> int:
    """One row's receive time, epoch µs."""
    return int(table.column(TIME)[row].cast(pa.int64()).as_py())


def write_segment(table: pa.Table, directory: Path, robot: str) -> Segment | None:
    """Write ``table`` (sorted by time) as a closed segment; ``None`` for an empty table."""
    if table.num_rows == 0:
        return None
    groups = (table.slice(o, ROW_GROUP_ROWS) for o in range(0, table.num_rows, ROW_GROUP_ROWS))
    return _write_segment(groups, directory, robot, str(_time_us(table, 0)))


def _write_segment(
    groups: Iterator[pa.Table], directory: Path, robot: str, scratch: str
) -> Segment | None:
    """``groups`` (in time order) as a closed segment, through temporary files named after
    ``scratch`` (the cells renamed into place first, then the Parquet: a ``.parquet`` exists
    only complete, with its cells); ``None`` for no rows."""
    parquet_tmp = directory / f"{scratch}{SEGMENT_SUFFIX}.tmp"
    try:
        with open(parquet_tmp, "wb") as sink:
            written = _write_parquet(groups, sink)
            sink.flush()
            os.fsync(sink.fileno())
        if written is None:
            return None
        cells, start_us, end_us = written
        name = f"{start_us}-{end_us}{SEGMENT_SUFFIX}"
        segment = Segment(robot, directory / name, start_us, end_us)
        write_cells(cells, segment.rollup_path)
        os.replace(parquet_tmp, segment.path)
        _fsync_dir(directory)
        return segment
    finally:
        with contextlib.suppress(OSError):
            parquet_tmp.unlink()


def _journal_groups(path: Path) -> Iterator[pa.Table]:
    """A journal's complete batches (a torn last one, from a crash, left out) in tables of
    ``ROW_GROUP_ROWS`` rows (the last one shorter) of the recording's schema
    (``schema.conform``), read a batch at a time and never copied: memory holds one group's
    batches (about 20 MB at 300 bytes a frame), never the whole journal."""
    pending: list[pa.RecordBatch] = []
    rows = 0
    with pa.OSFile(str(path), "rb") as source:
        try:
            reader = pa.ipc.open_stream(source)
        except (OSError, pa.ArrowException):  # empty, or its schema torn
            return
        check_versions(JOURNAL, reader.schema.metadata, path)  # a newer one stays a journal
        while True:
            try:
                batch = reader.read_next_batch()
            except StopIteration:
                break
            except (OSError, pa.ArrowException):  # a batch torn by a crash: the end
                break
            pending.append(batch)
            rows += batch.num_rows
            while rows >= ROW_GROUP_ROWS:
                table = pa.Table.from_batches(pending, schema=reader.schema)
                pending = table.slice(ROW_GROUP_ROWS).to_batches()
                rows -= ROW_GROUP_ROWS
                group = conform(_expanded(table.slice(0, ROW_GROUP_ROWS)), SCHEMA.names)
                del table  # the group holds its batches; the next ones are read meanwhile
                yield group
                del group
        if rows:
            table = pa.Table.from_batches(pending, schema=reader.schema)
            yield conform(_expanded(table), SCHEMA.names)


def _expanded(table: pa.Table) -> pa.Table:
    """A row group of a journal as the recording's columns: a journal of payloads is sliced
    into element columns ``EXPAND_ROWS`` rows at a time (``journal_form``)."""
    if not is_journal_form(table.schema):
        return table
    # In slices of a few thousand rows: slicing unpacks each payload's bits to a byte each
    # (2272 bytes a row, 150 MB for a whole group at once), and each slice's payloads are
    # copied together (``combine_chunks``) a slice at a time, never the group's.
    expanded = [
        expand(batch)
        for start in range(0, table.num_rows, EXPAND_ROWS)
        for batch in table.slice(start, EXPAND_ROWS).combine_chunks().to_batches()
    ]
    return pa.Table.from_batches(expanded, schema=SCHEMA)


def close_journal(path: Path, robot: str) -> Segment | None:
    """Turn a journal into a closed segment and delete it (also after a crash), a row group at
    a time (memory holds about one, 64 Ki rows, and its cells). A journal of a newer format
    raises ``FormatVersionError`` and stays as it is. The service does this in a
    process of its own (``close_process``), whose memory leaves with it."""
    forget_journal(path)
    segment = _write_segment(_journal_groups(path), path.parent, robot, path.name)
    path.unlink(missing_ok=True)
    return segment


def recover(root: Path, robot: str) -> list[Segment]:
    """Close every journal a crash left behind; the closed segments made (a journal of a
    newer format is left as it is)."""
    made = []
    for _, path in list_journals(root, robot):
        try:
            segment = close_journal(path, robot)
        except FormatVersionError:
            continue
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
            # The batch's form decides the journal's: the recorder's batches are payloads
            # (journal_form); a batch of element columns makes a journal of them.
            schema = batch.schema.with_metadata(
                {**(batch.schema.metadata or {}), **version_metadata(JOURNAL)}
            )
            writer = pa.ipc.new_stream(sink, schema)
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
        path = self.finish_journal()
        return None if path is None else close_journal(path, self.robot)

    def finish_journal(self) -> Path | None:
        """Close the journal's file and give its path, for ``close_journal`` here or on
        another thread (``closer``); the next batch opens a new journal. ``None``: nothing
        open."""
        path = self._path
        self._abandon()
        return path

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
