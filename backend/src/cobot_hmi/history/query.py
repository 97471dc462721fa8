"""Layer: history storage. Imports only the history schema, rollup and segments, and
``stored_format``'s error.

A range of a robot's recording, decimated for a plot of ``points`` buckets, without losing a
peak (the M4 idea: per bucket the min, the max, the first and the last value, so a line drawn
through them has every extreme of the raw frames):

- fewer frames in the range than ``points``: the raw frames themselves (``mode="raw"``);
- buckets narrower than a second: buckets of ``(to - from) / points`` from ``from``, reduced
  from the raw frames;
- buckets of a second or more: a whole number of seconds wide, their edges whole multiples of
  the width since the epoch, reduced from the cells (``rollup``): exact (a bucket is a union of
  whole cells). The cells are the coarsest of ``rollup.LEVELS_S`` (1 s, 10 s, 1 min) whose
  width the bucket can be a multiple of while it grows by at most ``LEVEL_SLACK`` (so an
  answer keeps at least 80 % of the points asked): a day at 1000 points has buckets of 90 s
  made of 8,640 ten-second cells instead of 86,400 per-second ones or 8.64 million frames.
  The first and last bucket may then reach past ``from`` and ``to`` to their edges.

Only non-empty buckets are answered; ``count`` says how many frames each holds. A file of a
newer format than this build reads (``formats``) is left out, with a warning naming it once.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from cobot_hmi.history.cells import read_cells_file
from cobot_hmi.history.rollup import (
    CELL,
    COUNT,
    LEVELS_S,
    STATS,
    T_FIRST,
    T_LAST,
    cell_starts,
    coarsen,
    reduce_runs,
    reduce_stat,
    rollup_table,
    stat_column,
)
from cobot_hmi.history.schema import (
    SCHEMA,
    SEQ,
    T2O_SEQUENCE,
    TIME,
    Element,
    conform,
    time_seconds,
)
from cobot_hmi.history.segments import (
    Segment,
    list_journals,
    list_segments,
    open_segment,
    read_journal,
)
from cobot_hmi.stored_format import FormatVersionError

log = logging.getLogger(__name__)

MAX_POINTS: Final = 5000
CELL_S: Final = 1.0
"""Width of the finest rollup cell, s."""
LEVEL_SLACK: Final = 1.25
"""How much wider than asked a bucket may grow to be made of coarser cells."""

F64 = npt.NDArray[np.float64]


_REFUSED: Final[set[str]] = set()
_REFUSED_LOCK: Final = threading.Lock()


def _left_out(error: FormatVersionError) -> None:
    """A file of a newer format is left out of every answer; said once per file."""
    with _REFUSED_LOCK:
        if error.where in _REFUSED:
            return
        _REFUSED.add(error.where)
    log.warning("history: left out of queries: %s", error)


class QueryError(ValueError):
    """A query that cannot be answered as asked; ``field`` names the parameter at fault."""

    def __init__(self, reason: str, field: str) -> None:
        super().__init__(reason)
        self.field = field


@dataclass(slots=True)
class Series:
    """One element's answer: ``values`` (raw) or ``min``/``max``/``first``/``last`` (buckets)."""

    element: Element
    values: np.ndarray | None = None
    stats: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass(slots=True)
class QueryResult:
    robot: str
    from_s: float
    to_s: float
    points: int
    mode: str
    """``raw`` or ``buckets``."""
    t: F64
    """Raw: each frame's receive time. Buckets: each non-empty bucket's start."""
    series: list[Series]
    bucket_s: float | None = None
    seq: npt.NDArray[np.int64] | None = None
    t2o_sequence: list[int | None] | None = None
    """Raw: each frame's T→O wire sequence number (``None``: recorded before the column)."""
    count: npt.NDArray[np.int64] | None = None
    t_first: F64 | None = None
    t_last: F64 | None = None
    frames: int = 0
    """Frames the answer covers."""
    cells_s: int | None = None
    """Buckets from the cells: the width of the cells read, s."""


def check_range(from_s: float, to_s: float, points: int) -> None:
    if not (math.isfinite(from_s) and math.isfinite(to_s)):
        raise QueryError("from and to must be finite times", "from")
    if to_s <= from_s:
        raise QueryError("'to' must be after 'from'", "to")
    if not 1 <= points <= MAX_POINTS:
        raise QueryError(f"points must be 1 to {MAX_POINTS}", "points")


# --------------------------------------------------------------------------- reading


def _sources(
    root: Path, robot: str, start_us: int, end_us: int
) -> tuple[list[Segment], list[Path]]:
    """The closed segments and the journals a range reads. The journals are listed first: one
    the recorder closes meanwhile shows up as its segment in the listing after, and a journal
    seen with its segment (closed, not yet deleted) is read as the segment only. One closed
    after both listings, before it is read, is read as its segment (``_journal_frames``)."""
    journals = list_journals(root, robot)
    closed = list_segments(root, robot)
    starts = {s.start_us for s in closed}
    return (
        [s for s in closed if s.end_us >= start_us and s.start_us < end_us],
        [path for start, path in journals if start < end_us and start not in starts],
    )


def _journal_frames(root: Path, robot: str, path: Path, columns: Sequence[str]) -> pa.Table:
    """A journal's frames; if the recorder closed it since it was listed (it is gone), its
    closed segment's (named by the same first receive time): a streamed export or a query
    reading the older segments first must not lose the newest ones."""
    try:
        table = read_journal(path, columns)
    except FormatVersionError as error:
        _left_out(error)
        return conform(SCHEMA.empty_table(), columns)
    if table.num_rows or path.exists():
        return table
    start_us = int(path.name.partition(".")[0])
    for segment in list_segments(root, robot):
        if segment.start_us == start_us:
            with contextlib.suppress(OSError, pa.ArrowException, FormatVersionError):
                return conform(open_segment(segment.path).read(columns=list(columns)), columns)
    return table


def iter_raw(
    root: Path, robot: str, columns: Sequence[str], from_s: float, to_s: float
) -> Iterator[pa.Table]:
    """Frames with ``from_s <= time < to_s``, ``columns`` only, a table per segment (closed
    ones, then the open one), oldest first: memory holds one segment at a time. A column a
    segment was written without (``t2o_sequence`` before it existed) is nulls."""
    start_us, end_us = math.floor(from_s * 1e6), math.ceil(to_s * 1e6)
    closed, journals = _sources(root, robot, start_us, end_us)
    for segment in closed:
        try:
            table = conform(open_segment(segment.path).read(columns=list(columns)), columns)
        except (OSError, pa.ArrowException):  # deleted by retention meanwhile
            continue
        except FormatVersionError as error:
            _left_out(error)
            continue
        # Compared as _clip compares (receive times in seconds), not by whole microseconds.
        partial = segment.start_us / 1e6 < from_s or segment.end_us / 1e6 >= to_s
        yield _clip(table, from_s, to_s, partial)
    for path in journals:
        yield _clip(_journal_frames(root, robot, path, columns), from_s, to_s, True)


def read_raw(
    root: Path, robot: str, elements: Sequence[Element], from_s: float, to_s: float
) -> pa.Table:
    """Frames with ``from_s <= time < to_s``: ``time``, ``seq``, ``t2o_sequence`` and the
    elements' columns."""
    columns = [TIME, SEQ, T2O_SEQUENCE, *(e.name for e in elements)]
    tables = list(iter_raw(root, robot, columns, from_s, to_s))
    if not tables:
        return pa.schema([SCHEMA.field(c) for c in columns]).empty_table()
    return pa.concat_tables(tables)


def _clip(table: pa.Table, from_s: float, to_s: float, needed: bool) -> pa.Table:
    if not needed or table.num_rows == 0:
        return table
    t = time_seconds(table)
    first, last = np.searchsorted(t, from_s, "left"), np.searchsorted(t, to_s, "left")
    return table.slice(int(first), int(last - first))


def read_cells(
    root: Path,
    robot: str,
    elements: Sequence[Element],
    first_cell: int,
    end_cell: int,
    *,
    width_s: int = 1,
) -> pa.Table:
    """Cells of ``width_s`` seconds (one of ``rollup.LEVELS_S``), ``first_cell <= cell <
    end_cell`` (multiples of ``width_s``), of closed segments and journals, in time order."""
    columns = [CELL, COUNT, T_FIRST, T_LAST]
    columns += [stat_column(e.name, s) for e in elements for s in STATS]
    start_us, end_us = first_cell * 1_000_000, end_cell * 1_000_000
    tables = []
    closed, journals = _sources(root, robot, start_us, end_us)
    for segment in closed:
        table: pa.Table | None
        try:
            table = read_cells_file(segment.rollup_path, columns, width_s)
            if table is None:  # a recording older than the coarser cells
                seconds = read_cells_file(segment.rollup_path, columns)
                table = None if seconds is None else coarsen(seconds, width_s)
        except (OSError, pa.ArrowException, FormatVersionError):
            table = None
        if table is None:
            try:  # a rollup lost or unreadable: made again from the frames
                raw = open_segment(segment.path).read()
            except (OSError, pa.ArrowException):
                continue
            except FormatVersionError as error:
                _left_out(error)
                continue
            table = coarsen(rollup_table(raw, list(elements)).select(columns), width_s)
        whole = segment.start_us >= start_us and segment.end_us < end_us
        tables.append(table if whole else _clip_cells(table, first_cell, end_cell))
    for path in journals:
        journal = _journal_frames(root, robot, path, [TIME, *(e.name for e in elements)])
        cells = coarsen(rollup_table(journal, list(elements)).select(columns), width_s)
        tables.append(_clip_cells(cells, first_cell, end_cell))
    if not tables:
        return pa.schema([]).empty_table()
    return pa.concat_tables(tables)


def _clip_cells(table: pa.Table, first_cell: int, end_cell: int) -> pa.Table:
    cells = table.column(CELL).to_numpy()
    first, last = (
        np.searchsorted(cells, first_cell, "left"),
        np.searchsorted(cells, end_cell, "left"),
    )
    return table.slice(int(first), int(last - first))


# --------------------------------------------------------------------------- answering


def query(
    root: Path,
    robot: str,
    elements: Sequence[Element],
    *,
    from_s: float,
    to_s: float,
    points: int,
) -> QueryResult:
    """The decimated range (module docstring); ``QueryError`` for a range it cannot answer."""
    check_range(from_s, to_s, points)
    width_s = (to_s - from_s) / points
    if width_s >= CELL_S:
        result = _from_cells(
            root, robot, elements, from_s=from_s, to_s=to_s, points=points, width_s=width_s
        )
        if result is not None:
            return result
    table = read_raw(root, robot, elements, from_s, to_s)
    t = time_seconds(table)
    if table.num_rows <= points:
        seq = table.column(SEQ).to_numpy(zero_copy_only=False)
        wire = table.column(T2O_SEQUENCE).to_pylist()
        series = [
            Series(e, values=np.asarray(table.column(e.name).to_numpy(zero_copy_only=False)))
            for e in elements
        ]
        return QueryResult(
            robot,
            from_s,
            to_s,
            points,
            "raw",
            t,
            series,
            seq=seq,
            t2o_sequence=wire,
            frames=table.num_rows,
        )
    index = np.floor((t - from_s) / width_s).astype(np.int64)
    np.clip(index, 0, points - 1, out=index)
    starts = cell_starts(index)
    ends = np.concatenate([starts[1:], [t.size]]).astype(np.intp)
    series = []
    for e in elements:
        values = np.asarray(table.column(e.name).to_numpy(zero_copy_only=False))
        series.append(Series(e, stats=reduce_runs(e, values, starts)))
    return QueryResult(
        robot,
        from_s,
        to_s,
        points,
        "buckets",
        (from_s + index[starts] * width_s).astype(np.float64),
        series,
        bucket_s=width_s,
        count=(ends - starts).astype(np.int64),
        t_first=t[starts],
        t_last=t[ends - 1],
        frames=table.num_rows,
    )


@dataclass(frozen=True, slots=True)
class Grid:
    """Whole-second buckets aligned on the epoch, and the cells they are made of."""

    bucket_s: int
    first_cell: int
    """Start of the first bucket, epoch s."""
    end_cell: int
    """End of the last bucket, epoch s."""
    cells_s: int
    """Width of the cells read (a divisor of ``bucket_s``), s."""


def bucket_grid(from_s: float, to_s: float, width_s: float) -> Grid:
    """The buckets of at least ``width_s`` (≥ 1 s) covering ``from_s``…``to_s``: as wide as
    asked rounded up to a whole second, or to a multiple of the coarsest cell width that makes
    them at most ``LEVEL_SLACK`` times wider (module docstring)."""
    bucket_s = max(1, math.ceil(width_s - 1e-9))
    cells_s = LEVELS_S[0]
    asked = bucket_s
    for level in LEVELS_S[1:]:
        rounded = math.ceil(asked / level) * level
        if rounded <= asked * LEVEL_SLACK:
            bucket_s, cells_s = rounded, level
    first_cell = math.floor(from_s / bucket_s) * bucket_s
    end_cell = math.ceil(to_s / bucket_s) * bucket_s
    if end_cell <= first_cell:
        end_cell = first_cell + bucket_s
    return Grid(bucket_s, first_cell, end_cell, cells_s)


def _from_cells(
    root: Path,
    robot: str,
    elements: Sequence[Element],
    *,
    from_s: float,
    to_s: float,
    points: int,
    width_s: float,
) -> QueryResult | None:
    """Whole-second buckets from the cells; ``None`` when the range holds ≤ ``points`` frames
    (the caller answers them raw)."""
    grid = bucket_grid(from_s, to_s, width_s)
    bucket_s, first_cell = grid.bucket_s, grid.first_cell
    cells = read_cells(root, robot, elements, first_cell, grid.end_cell, width_s=grid.cells_s)
    if cells.num_rows == 0:
        return None
    counts = cells.column(COUNT).to_numpy().astype(np.int64)
    if int(counts.sum()) <= points:
        return None
    cell = cells.column(CELL).to_numpy()
    index = (cell - first_cell) // bucket_s
    starts = cell_starts(index)
    ends = np.concatenate([starts[1:], [cell.size]]).astype(np.intp)
    series = []
    for e in elements:
        stats = {}
        for s in STATS:
            values = np.asarray(cells.column(stat_column(e.name, s)).to_numpy(zero_copy_only=False))
            stats[s] = reduce_stat(e, s, values, starts)
        series.append(Series(e, stats=stats))
    t_first = cells.column(T_FIRST).to_numpy()
    t_last = cells.column(T_LAST).to_numpy()
    return QueryResult(
        robot,
        from_s,
        to_s,
        points,
        "buckets",
        (first_cell + index[starts] * bucket_s).astype(np.float64),
        series,
        bucket_s=float(bucket_s),
        count=np.add.reduceat(counts, starts),
        t_first=t_first[starts],
        t_last=t_last[ends - 1],
        frames=int(counts.sum()),
        cells_s=grid.cells_s,
    )
