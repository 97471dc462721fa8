"""Layer: plant (a door above the service). The plant history's files, written and read: their
schema, their format's version, the compacted segment's layout and the reading of one series
from them by the files' own statistics (``recorder.py`` decides when files are written; a
trend asks for one metric of one device over hours, ``PlantRecorder.trend_table``).

Versions of the format (``PLANT_SEGMENT``; every file says its own in its Parquet metadata):

- 1: rows in time order, one row group of up to 1 Mi rows. A trend over days read every row of
  every hour (a metric's rows are spread over every row group), seconds per hour of a large
  plant.
- 2 (today): a compacted segment's rows in series order (group, node, device, metric) and then
  time, in row groups of ``ROW_GROUP_ROWS``, each row group's first and last series named in the
  metadata (``ROW_GROUP_KEYS``): a series is read from the one or two row groups that hold it.
  Parts (a second's rows, one small row group) stay in arrival order: they are read whole.

Both are read: a version 1 file through its row groups' column statistics (time only prunes
there), a version 2 one through its row-group keys. Each file's row-group keys (or ranges) are
kept in memory (``FILE_INDEX_LIMIT`` files): a compacted segment never changes, and a trend
over a week opens 168 of them; the footer itself is read again for each read (kept, its
statistics parsed are some 1.5 MB an hour).

Imports ``stored_format`` only.
"""

from __future__ import annotations

import functools
import json
import logging
import sys
import threading
from bisect import bisect_left, bisect_right
from collections import OrderedDict
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from cobot_hmi.stored_format import FormatVersionError, StoredFormat

log = logging.getLogger(__name__)

PLANT_SEGMENT = StoredFormat("plant history segment", 2)
VERSION_KEY: Final = b"cobot_hmi.format_version"
ABSORBED_KEY: Final = b"cobot_hmi.absorbed_parts"
ROW_GROUP_KEYS: Final = b"cobot_hmi.row_group_keys"
"""Version 2: JSON, per row group ``[first series, last series]``, each ``[group, node,
device, metric]``."""
ROW_GROUP_ROWS: Final = 8192
"""A compacted segment's row group: a series is read as one or two of them (an hour of a
500-robot plant, 1.8 M rows, is some 220: a footer of about 100 kB, read once)."""
SERIES: Final = ("group", "node", "device", "metric")
VALUES: Final = ("time_ms", "value", "text", "historical")
FILE_INDEX_LIMIT: Final = 1024
"""Files whose index is kept (six weeks of hours, some 40 MB at most for 500 robots)."""
READ_THREADS: Final = 4
"""Files read at once by one trend (Parquet decoding runs without the GIL)."""
SCHEMA: Final = pa.schema(
    [
        ("time_ms", pa.int64()),
        ("group", pa.string()),
        ("node", pa.string()),
        ("device", pa.string()),
        ("metric", pa.string()),
        ("value", pa.float64()),
        ("text", pa.string()),
        ("historical", pa.bool_()),
    ],
    metadata={VERSION_KEY: str(PLANT_SEGMENT.version).encode()},
)

Series = tuple[str, str, str, str]
"""(group, node, device, metric)."""


def write_segment(path: Path, table: pa.Table, absorbed: list[str]) -> None:
    """A compacted segment (version 2) at ``path``: ``table``'s rows in series order, then time;
    row groups of ``ROW_GROUP_ROWS`` with each one's first and last series in the metadata;
    ``absorbed`` the parts it holds (``recorder.py``: a reader never counts a row twice)."""
    ordered = table.cast(SCHEMA).sort_by([(name, "ascending") for name in (*SERIES, "time_ms")])
    keys = []
    columns = [ordered[name] for name in SERIES]
    for start in range(0, ordered.num_rows, ROW_GROUP_ROWS):
        last = min(start + ROW_GROUP_ROWS, ordered.num_rows) - 1
        keys.append([[c[start].as_py() for c in columns], [c[last].as_py() for c in columns]])
    metadata = {
        **(SCHEMA.metadata or {}),
        ABSORBED_KEY: json.dumps(absorbed).encode(),
        ROW_GROUP_KEYS: json.dumps(keys, separators=(",", ":")).encode(),
    }
    pq.write_table(
        ordered.replace_schema_metadata(metadata),
        path,
        row_group_size=ROW_GROUP_ROWS,
        # Statistics of what a read chooses row groups by only: a smaller footer, read sooner.
        write_statistics=[*SERIES, "time_ms"],
    )


@dataclass(frozen=True, slots=True)
class _FileIndex:
    """What a file's footer says that choosing its row groups needs (kept: ``file_index``; not
    the footer itself, which parsed is some 1.5 MB for an hour of 500 robots: this is ~40 kB)."""

    version: int
    absorbed: tuple[str, ...]
    groups: int
    first_keys: list[Series] | None
    """Version 2 segments: each row group's first and last series (sorted: bisected)."""
    last_keys: list[Series] | None
    statistics: list[dict[str, tuple[object, object]]]
    """Files without row-group keys (parts, version 1): per row group, each key column's and the
    time's (min, max) where the file has them (a part is one row group, version 1 a few)."""


_INDEX: OrderedDict[tuple[str, int, int], _FileIndex] = OrderedDict()
_INDEX_LOCK = threading.Lock()


def _ranges(metadata: pq.FileMetaData, group: int) -> dict[str, tuple[object, object]]:
    """A row group's key columns' and time's (min, max), where the file has them."""
    row_group = metadata.row_group(group)
    ranges: dict[str, tuple[object, object]] = {}
    for i in range(metadata.num_columns):
        name = metadata.schema.column(i).name
        stats = row_group.column(i).statistics
        if name in (*SERIES, "time_ms") and stats is not None and stats.has_min_max:
            ranges[name] = (stats.min, stats.max)
    return ranges


def _series_of(key: list[str]) -> Series:
    """A row-group key, its names shared with every other file's (``sys.intern``)."""
    group, node, device, metric = (sys.intern(str(part)) for part in key)
    return group, node, device, metric


def _load_index(path: Path, metadata: pq.FileMetaData) -> _FileIndex:
    found = metadata.metadata or {}
    version = PLANT_SEGMENT.read_version(found.get(VERSION_KEY), path)
    absorbed = json.loads(found[ABSORBED_KEY]) if ABSORBED_KEY in found else []
    first_keys = last_keys = None
    len_groups = metadata.num_row_groups
    if version >= 2 and ROW_GROUP_KEYS in found:
        keys = json.loads(found[ROW_GROUP_KEYS])
        if len(keys) == metadata.num_row_groups:
            first_keys = [_series_of(k[0]) for k in keys]
            last_keys = [_series_of(k[1]) for k in keys]
    return _FileIndex(
        version,
        tuple(str(n) for n in absorbed) if isinstance(absorbed, list) else (),
        len_groups,
        first_keys,
        last_keys,
        [] if first_keys is not None else [_ranges(metadata, g) for g in range(len_groups)],
    )


def file_index(path: Path) -> _FileIndex:
    """``path``'s index, read once while the file is unchanged (its size and time say so).
    Raises ``FormatVersionError`` for a newer format, ``OSError``/``ArrowException`` for a
    file that cannot be read."""
    return _indexed(path)[0]


def _indexed(path: Path) -> tuple[_FileIndex, pq.FileMetaData | None]:
    """``path``'s index, and its footer when it was read for it just now (the read after uses
    it rather than reading it again)."""
    stat = path.stat()
    key = (str(path), stat.st_mtime_ns, stat.st_size)
    with _INDEX_LOCK:
        found = _INDEX.get(key)
        if found is not None:
            _INDEX.move_to_end(key)
            return found, None
    metadata = pq.read_metadata(path)
    index = _load_index(path, metadata)
    with _INDEX_LOCK:
        _INDEX[key] = index
        while len(_INDEX) > FILE_INDEX_LIMIT:
            _INDEX.popitem(last=False)
    return index, metadata


def forget_indexes() -> None:
    """Drop every kept footer (a cold read, as after a start: ``bench/plant_trend``)."""
    with _INDEX_LOCK:
        _INDEX.clear()


def absorbed_parts(segment: Path) -> list[str]:
    """The names of the parts a segment holds (its metadata), empty when it cannot say."""
    try:
        return list(file_index(segment).absorbed)
    except (OSError, ValueError, pa.ArrowException):
        return []


def _row_groups(index: _FileIndex, series: Series, start_ms: int, end_ms: int) -> list[int]:
    """The row groups that may hold ``series`` in ``[start_ms, end_ms]``."""
    if index.first_keys is not None and index.last_keys is not None:
        # Sorted by series: the row groups whose [first, last] contains it, a contiguous run.
        low = bisect_left(index.last_keys, series)
        high = bisect_right(index.first_keys, series)
        return list(range(low, high))  # the time: in the mask (a row group spans the hour)
    chosen = []
    wanted = dict(zip(SERIES, series, strict=True))
    for g in range(index.groups):
        ranges = index.statistics[g]
        if any(
            name in ranges and not ranges[name][0] <= value <= ranges[name][1]  # type: ignore[operator]
            for name, value in wanted.items()
        ):
            continue
        times = ranges.get("time_ms")
        if times is not None and (times[1] < start_ms or times[0] > end_ms):  # type: ignore[operator]
            continue
        chosen.append(g)
    return chosen


def read_series(path: Path, series: Series, start_ms: int, end_ms: int) -> pa.Table | None:
    """One file's rows of ``series`` in ``[start_ms, end_ms]`` (columns ``VALUES``); ``None``
    when it cannot be read or is of a newer format (named in the log, left on disk)."""
    try:
        index, metadata = _indexed(path)
        groups = _row_groups(index, series, start_ms, end_ms)
        if not groups:
            return None
        # The series' columns as dictionaries: compared by index, never made into strings.
        table = pq.ParquetFile(
            path, metadata=metadata, read_dictionary=list(SERIES)
        ).read_row_groups(groups, columns=[*SERIES, *VALUES], use_threads=False)
    except FormatVersionError as error:
        log.warning("plant history: %s", error)
        return None
    except (OSError, pa.ArrowException) as error:
        log.warning("plant history: %s unreadable: %s", path, error)
        return None
    mask = pc.and_(
        pc.greater_equal(table["time_ms"], start_ms), pc.less_equal(table["time_ms"], end_ms)
    )
    for name, value in zip(SERIES, series, strict=True):
        mask = pc.and_(mask, _equal(table[name], value))
    return table.filter(mask).select(list(VALUES))


def _equal(column: pa.ChunkedArray, value: str) -> pa.ChunkedArray:
    """Where a column (dictionaries, one per row group) holds ``value``."""
    chunks = []
    for chunk in column.chunks:
        if not isinstance(chunk, pa.DictionaryArray):
            chunks.append(pc.equal(chunk, value))
            continue
        position = pc.index(chunk.dictionary, value).as_py()
        if position < 0:
            chunks.append(pa.nulls(len(chunk), pa.bool_()).fill_null(False))
        else:
            chunks.append(pc.equal(chunk.indices, pa.scalar(position, chunk.indices.type)))
    return pa.chunked_array(chunks, pa.bool_())


@functools.cache
def _pool() -> ThreadPoolExecutor:
    """The trend's readers, made at the first trend (a process that never asks has none)."""
    return ThreadPoolExecutor(READ_THREADS, thread_name_prefix="plant-trend")


def read_series_files(paths: list[Path], series: Series, start_ms: int, end_ms: int) -> pa.Table:
    """``series`` in ``[start_ms, end_ms]`` from every file of ``paths``, in time order
    (columns ``VALUES``), the files read ``READ_THREADS`` at a time."""
    if len(paths) > 1:
        found = list(_pool().map(lambda p: read_series(p, series, start_ms, end_ms), paths))
    else:
        found = [read_series(p, series, start_ms, end_ms) for p in paths]
    tables = [t for t in found if t is not None and t.num_rows]
    if not tables:
        return SCHEMA.empty_table().select(list(VALUES))
    return pa.concat_tables(tables).sort_by("time_ms")


def read_whole(path: Path) -> pa.Table | None:
    """A file's every row (compaction), ``None`` as ``read_series``."""
    try:
        file_index(path)  # its version checked
        table = pq.read_table(path, schema=SCHEMA)
    except FormatVersionError as error:
        log.warning("plant history: %s", error)
        return None
    except (OSError, pa.ArrowException) as error:
        log.warning("plant history: %s unreadable: %s", path, error)
        return None
    return table.filter(pc.is_valid(table["time_ms"]))
