"""Layer: plant (a door above the service). Everything the plant receives, recorded: each
metric value (live or historical) a row of hourly Parquet segments under the state directory,
so a trend of any metric of any robot over days is read from disk without the cells.

``plant-history/<YYYY-MM-DDTHH>/`` holds an hour (UTC, by the value's own time: a cell's
historical values land in the hour they happened): parts written every ``FLUSH_S`` while the
hour is open, compacted into one ``segment.parquet`` once it has been over for
``COMPACT_AFTER_S`` (a part that comes later, a late replay, is read beside it). Every file says
its format's version in its Parquet metadata (``stored_format``); a newer one is left out of
queries, named in the log. A query reads only the hours of its range, and of each only the row
groups that hold its series (the files' layout and reading: ``segments.py``).

Imports ``segments`` and the plant's host (its ``Sample``).
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Final

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from cobot_hmi.plant.host import Sample, SampleColumns, SampleRow, SeriesIds
from cobot_hmi.plant.segments import (
    ABSORBED_KEY,
    PLANT_SEGMENT,
    SCHEMA,
    VERSION_KEY,
    absorbed_parts,
    read_series_files,
    read_whole,
    write_segment,
)

log = logging.getLogger(__name__)

__all__ = ["ABSORBED_KEY", "PLANT_SEGMENT", "SCHEMA", "VERSION_KEY", "PlantRecorder"]

FLUSH_S: Final = 1.0
COMPACT_AFTER_S: Final = 600.0
SEGMENT: Final = "segment.parquet"
_HOUR_FORMAT: Final = "%Y-%m-%dT%H"
HOUR_MS: Final = 3_600_000


@dataclass(frozen=True, slots=True)
class MetricKey:
    """One metric of one device (``device`` empty: the node's own)."""

    group: str
    node: str
    device: str
    metric: str


@dataclass(frozen=True, slots=True)
class Point:
    time_ms: int
    value: float | None
    text: str | None
    historical: bool


@functools.lru_cache(maxsize=256)
def _hour_name(hour: int) -> str:
    """An hour's folder name (cached: the rows of a flush are nearly all of the same hour)."""
    return datetime.fromtimestamp(hour * HOUR_MS / 1000, UTC).strftime(_HOUR_FORMAT)


class _SeriesColumns:
    """The series' names as Arrow columns (group, node, device, metric by series number), the
    names of series added since the last flush appended (a plant's births add thousands):
    a flush's name columns are taken from them by number."""

    def __init__(self, series: SeriesIds) -> None:
        self._series = series
        self._columns: list[pa.Array] = [pa.array([], pa.string()) for _ in range(4)]
        self._count = 0

    def columns(self) -> list[pa.Array]:
        names = self._series.names
        count = len(names)  # what the host adds after this is in no row of this flush
        if count != self._count:
            added = names[self._count : count]
            self._columns = [
                pa.concat_arrays([column, pa.array([name[i] for name in added], pa.string())])
                for i, column in enumerate(self._columns)
            ]
            self._count = count
        return self._columns


def _table(samples: SampleColumns, names: list[pa.Array]) -> pa.Table:
    """Columns to an Arrow table: the names taken by series number, the values split by kind
    (numbers and booleans as numbers in one C-level step unless a text is among them)."""
    series = pa.array(samples.series, pa.int32())
    group, node, device, metric = (column.take(series) for column in names)
    values = samples.values
    try:
        value = pa.array(values, pa.float64())
        text = pa.nulls(len(values), pa.string())
    except pa.ArrowInvalid:  # texts among them
        value = pa.array([v if type(v) is float else _numeric(v) for v in values], pa.float64())
        text = pa.array([v if type(v) is str else None for v in values], pa.string())
    return pa.table(
        {
            "time_ms": pa.array(samples.times_ms, pa.int64()),
            "group": group,
            "node": node,
            "device": device,
            "metric": metric,
            "value": value,
            "text": text,
            "historical": pa.array(samples.historical, pa.bool_()),
        },
        schema=SCHEMA,
    )


def _by_hour(samples: SampleColumns, names: list[pa.Array]) -> list[tuple[str, pa.Table]]:
    """The samples as a table per hour (UTC, by each value's own time), the hours in order."""
    if not len(samples):
        return []
    table = _table(samples, names)
    hours = pc.divide(table["time_ms"], pa.scalar(HOUR_MS, pa.int64()))
    first, last = pc.min_max(hours).values()
    if first == last:
        return [(_hour_name(first.as_py()), table)]
    return [
        (_hour_name(hour), table.filter(pc.equal(hours, pa.scalar(hour, pa.int64()))))
        for hour in sorted(pc.unique(hours).to_pylist())
    ]


def _samples(table: pa.Table) -> list[Sample]:
    """A table's rows as samples again (kept for the next flush when they could not be
    written)."""
    columns = [table[c].to_pylist() for c in ("time_ms", "group", "node", "device", "metric")]
    values = [
        text if text is not None else value
        for value, text in zip(table["value"].to_pylist(), table["text"].to_pylist(), strict=True)
    ]
    historical = table["historical"].to_pylist()
    return [Sample(*row) for row in zip(*columns, values, historical, strict=True)]


def _numeric(value: object) -> float | None:
    if isinstance(value, bool):
        return 1.0 if value else 0.0
    if isinstance(value, int | float):
        return float(value)
    return None


class PlantRecorder:
    """Samples in (from the event loop), hourly segments out (``flush`` on a worker thread).
    ``series``: the host's (``HostApplication.series``), whose numbers the columns it gives
    ``add_columns`` carry; by default one of its own."""

    def __init__(self, directory: Path, series: SeriesIds | None = None) -> None:
        self.directory = directory
        self.series = series if series is not None else SeriesIds()
        self._names = _SeriesColumns(self.series)
        self._pending = SampleColumns()
        self._lock = threading.Lock()
        self._part = 0
        self.rows_written = 0
        self.write_errors = 0

    def add(self, samples: Iterable[SampleRow]) -> None:
        """Rows given by name."""
        columns = SampleColumns()
        for row in samples:
            columns.append(row, self.series)
        self.add_columns(columns)

    def add_columns(self, columns: SampleColumns) -> None:
        """Rows whose series are numbered by ``self.series`` (the host's)."""
        with self._lock:
            self._pending.extend(columns)

    def flush(self) -> int:
        """Write what came since the last flush, a part per hour; compact finished hours. What
        cannot be written (a full disk) stays pending for the next flush."""
        with self._lock:
            pending, self._pending = self._pending, SampleColumns()
        written = 0
        for hour, table in _by_hour(pending, self._names.columns()):
            try:
                self._write_part(hour, table)
            except OSError as error:
                self.write_errors += 1
                log.warning("plant history: hour %s not written (%s): kept for later", hour, error)
                self.add(_samples(table))
                continue
            written += table.num_rows
        self.rows_written += written
        self._compact_finished()
        return written

    def _write_part(self, hour: str, table: pa.Table) -> None:
        folder = self.directory / hour
        folder.mkdir(parents=True, exist_ok=True)
        self._part += 1
        name = f"part-{time.time_ns()}-{self._part}.parquet"
        temporary = folder / (name + ".tmp")
        pq.write_table(table, temporary)
        os.replace(temporary, folder / name)

    def _compact_finished(self) -> None:
        """Hours over for ``COMPACT_AFTER_S``: their parts (and segment) into one segment."""
        if not self.directory.is_dir():
            return
        cutoff = datetime.now(UTC) - timedelta(hours=1, seconds=COMPACT_AFTER_S)
        for folder in sorted(self.directory.iterdir()):
            try:
                started = datetime.strptime(folder.name, _HOUR_FORMAT).replace(tzinfo=UTC)
            except ValueError:
                continue
            parts = sorted(folder.glob("part-*.parquet"))
            if started > cutoff or not parts:
                continue
            self._compact(folder, parts)

    @staticmethod
    def _compact(folder: Path, parts: list[Path]) -> None:
        """The parts read (and the segment, if any) into one segment that names the parts it
        absorbed, so a reader in between never counts a row twice; then those parts removed. A
        segment or part this build cannot read (a newer format, damage) is never overwritten
        nor removed."""
        segment = folder / SEGMENT
        tables = []
        absorbed: list[str] = []
        if segment.exists():
            table = read_whole(segment)
            if table is None:
                return
            tables.append(table)
            absorbed = absorbed_parts(segment)
        read = []
        for part in parts:
            if part.name in absorbed:  # a removal the last compaction did not finish
                with contextlib.suppress(OSError):
                    part.unlink()
                continue
            table = read_whole(part)
            if table is not None:
                tables.append(table)
                read.append(part)
        if not read:
            return
        temporary = folder / (SEGMENT + ".tmp")
        write_segment(temporary, pa.concat_tables(tables), absorbed + [p.name for p in read])
        os.replace(temporary, segment)
        for part in read:
            with contextlib.suppress(OSError):
                part.unlink()

    def hour_files(self, start_ms: int, end_ms: int) -> list[Path]:
        """The files of the hours of ``[start_ms, end_ms]``: each hour's segment and its parts
        that the segment does not hold yet."""
        files: list[Path] = []
        hour = datetime.fromtimestamp(start_ms / 1000, UTC).replace(
            minute=0, second=0, microsecond=0
        )
        while hour.timestamp() * 1000 <= end_ms:
            folder = self.directory / hour.strftime(_HOUR_FORMAT)
            hour += timedelta(hours=1)
            if not folder.is_dir():
                continue
            found = sorted(folder.glob("*.parquet"))
            segment = folder / SEGMENT
            # Only an hour with parts beside its segment asks the segment which it holds (a
            # compacted hour's footer is read by the reader's threads, not here, one by one).
            holds = segment in found and len(found) > 1
            absorbed = set(absorbed_parts(segment)) if holds else set()
            files.extend(
                path
                for path in found
                if path.name not in absorbed  # already in the segment, not yet removed
            )
        return files

    def trend_table(self, key: MetricKey, start_ms: int, end_ms: int) -> pa.Table:
        """One metric's rows in ``[start_ms, end_ms]`` in time order (columns ``time_ms``,
        ``value``, ``text``, ``historical``)."""
        series = (key.group, key.node, key.device, key.metric)
        return read_series_files(self.hour_files(start_ms, end_ms), series, start_ms, end_ms)

    def trend(self, key: MetricKey, start_ms: int, end_ms: int) -> list[Point]:
        """Every recorded value of one metric in ``[start_ms, end_ms]``, in time order."""
        return points_of(self.trend_table(key, start_ms, end_ms))


def points_of(table: pa.Table) -> list[Point]:
    """A trend table's rows as points."""
    return [
        Point(t, v, x, h)
        for t, v, x, h in zip(
            table["time_ms"].to_pylist(),
            table["value"].to_pylist(),
            table["text"].to_pylist(),
            table["historical"].to_pylist(),
            strict=True,
        )
    ]
