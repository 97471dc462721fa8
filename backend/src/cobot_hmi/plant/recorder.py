"""Layer: plant (a door above the service). Everything the plant receives, recorded: each
metric value (live or historical) a row of hourly Parquet segments under the state directory,
so a trend of any metric of any robot over days is read from disk without the cells.

``plant-history/<YYYY-MM-DDTHH>/`` holds an hour (UTC, by the value's own time: a cell's
historical values land in the hour they happened): parts written every ``FLUSH_S`` while the
hour is open, compacted into one ``segment.parquet`` once it has been over for
``COMPACT_AFTER_S`` (a part that comes later, a late replay, is read beside it). Every file says
its format's version in its Parquet metadata (``stored_format``); a newer one is left out of
queries, named in the log. A query reads only the hours of its range.

Imports ``stored_format`` and the plant's host (its ``Sample``).
"""

from __future__ import annotations

import contextlib
import functools
import json
import logging
import operator
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

from cobot_hmi.plant.host import Sample
from cobot_hmi.stored_format import FormatVersionError, StoredFormat

log = logging.getLogger(__name__)

PLANT_SEGMENT = StoredFormat("plant history segment", 1)
VERSION_KEY: Final = b"cobot_hmi.format_version"
ABSORBED_KEY: Final = b"cobot_hmi.absorbed_parts"
FLUSH_S: Final = 1.0
COMPACT_AFTER_S: Final = 600.0
SEGMENT: Final = "segment.parquet"
_HOUR_FORMAT: Final = "%Y-%m-%dT%H"
HOUR_MS: Final = 3_600_000
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


def _table(samples: list[Sample]) -> pa.Table:
    """Rows to columns (a C-level pass each: the samples are tuples), values split by kind."""
    times, groups, nodes, devices, metrics, values, historical = (
        list(map(operator.itemgetter(column), samples)) for column in range(7)
    )
    return pa.table(
        {
            "time_ms": times,
            "group": groups,
            "node": nodes,
            "device": devices,
            "metric": metrics,
            "value": [v if type(v) is float else _numeric(v) for v in values],
            "text": [v if type(v) is str else None for v in values],
            "historical": historical,
        },
        schema=SCHEMA,
    )


def _by_hour(samples: list[Sample]) -> list[tuple[str, pa.Table]]:
    """The samples as a table per hour (UTC, by each value's own time), the hours in order."""
    if not samples:
        return []
    table = _table(samples)
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
    """Samples in (from the event loop), hourly segments out (``flush`` on a worker thread)."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self._pending: list[Sample] = []
        self._lock = threading.Lock()
        self._part = 0
        self.rows_written = 0
        self.write_errors = 0

    def add(self, samples: Iterable[Sample]) -> None:
        with self._lock:
            self._pending.extend(samples)

    def flush(self) -> int:
        """Write what came since the last flush, a part per hour; compact finished hours. What
        cannot be written (a full disk) stays pending for the next flush."""
        with self._lock:
            pending, self._pending = self._pending, []
        written = 0
        for hour, table in _by_hour(pending):
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
            table = _read(segment)
            if table is None:
                return
            tables.append(table)
            absorbed = _absorbed(segment)
        read = []
        for part in parts:
            if part.name in absorbed:  # a removal the last compaction did not finish
                with contextlib.suppress(OSError):
                    part.unlink()
                continue
            table = _read(part)
            if table is not None:
                tables.append(table)
                read.append(part)
        if not read:
            return
        merged = pa.concat_tables(tables).sort_by("time_ms")
        names = json.dumps(absorbed + [p.name for p in read]).encode()
        metadata = {**(SCHEMA.metadata or {}), ABSORBED_KEY: names}
        temporary = folder / (SEGMENT + ".tmp")
        pq.write_table(merged.replace_schema_metadata(metadata), temporary)
        os.replace(temporary, segment)
        for part in read:
            with contextlib.suppress(OSError):
                part.unlink()

    def trend(self, key: MetricKey, start_ms: int, end_ms: int) -> list[Point]:
        """Every recorded value of one metric in ``[start_ms, end_ms]``, in time order."""
        hours = []
        hour = datetime.fromtimestamp(start_ms / 1000, UTC).replace(
            minute=0, second=0, microsecond=0
        )
        while hour.timestamp() * 1000 <= end_ms:
            hours.append(self.directory / hour.strftime(_HOUR_FORMAT))
            hour += timedelta(hours=1)
        tables = []
        for folder in hours:
            if not folder.is_dir():
                continue
            segment = folder / SEGMENT
            absorbed = set(_absorbed(segment)) if segment.exists() else set()
            for path in sorted(folder.glob("*.parquet")):
                if path.name in absorbed:  # already in the segment, not yet removed
                    continue
                table = _read(path, (key, start_ms, end_ms))
                if table is not None and table.num_rows:
                    tables.append(table)
        if not tables:
            return []
        merged = pa.concat_tables(tables).sort_by("time_ms")
        return [
            Point(t, v, x, h)
            for t, v, x, h in zip(
                merged["time_ms"].to_pylist(),
                merged["value"].to_pylist(),
                merged["text"].to_pylist(),
                merged["historical"].to_pylist(),
                strict=True,
            )
        ]


def _absorbed(segment: Path) -> list[str]:
    """The names of the parts a segment holds (its metadata), empty when it cannot say."""
    try:
        found = (pq.read_schema(segment).metadata or {}).get(ABSORBED_KEY)
        names = json.loads(found) if found else []
    except (OSError, ValueError, pa.ArrowException):
        return []
    return [str(n) for n in names] if isinstance(names, list) else []


def _read(path: Path, where: tuple[MetricKey, int, int] | None = None) -> pa.Table | None:
    """One file's rows (of one metric in a range, with ``where``); ``None`` when it cannot be
    read or is of a newer format (named in the log, left on disk)."""
    try:
        metadata = pq.read_schema(path).metadata or {}
        PLANT_SEGMENT.read_version(metadata.get(VERSION_KEY), path)
        if where is None:
            return pq.read_table(path, schema=SCHEMA)
        key, start_ms, end_ms = where
        table = pq.read_table(
            path,
            columns=["time_ms", "value", "text", "historical"],
            filters=[
                ("group", "=", key.group),
                ("node", "=", key.node),
                ("device", "=", key.device),
                ("metric", "=", key.metric),
                ("time_ms", ">=", start_ms),
                ("time_ms", "<=", end_ms),
            ],
        )
    except FormatVersionError as error:
        log.warning("plant history: %s", error)
        return None
    except (OSError, pa.ArrowException) as error:
        log.warning("plant history: %s unreadable: %s", path, error)
        return None
    return table.filter(pc.is_valid(table["time_ms"]))
