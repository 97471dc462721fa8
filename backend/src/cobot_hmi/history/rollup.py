"""Layer: history storage. Imports only the history schema, numpy and pyarrow.

Cells of a recording: for every element the min, max, first and last value of the frames
received in one whole cell of the epoch (a second; ``LEVELS_S``), plus the cell's frame count
and its first and last receive times. A closed segment keeps its cells beside it
(``*.cells.arrow``), so a query of a long range reads one row per cell instead of a hundred
frames per second, and stays exact: a bucket made of whole cells has exactly the
min/max/first/last of its frames (``query``).

Coarser cells (10 s, 1 min) are made from the per-second ones (``coarsen``), not from the
frames: min/max/first/last compose (the min of the minima is the minimum, the first of the
firsts is the first), so a coarse cell is exactly what its frames would give, for a sixtieth
of the reading. A day at 1000 points reads 8,640 ten-second cells per element instead of
86,400 per-second ones.

Floats use ``fmin``/``fmax``: a NaN frame does not hide the others' extremes; a cell of NaNs
only is NaN.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Final

import numpy as np
import numpy.typing as npt
import pyarrow as pa

from cobot_hmi.history.schema import ELEMENTS, Element, time_seconds

CELL: Final = "cell"
"""Epoch second of the cell (``int64``)."""
COUNT: Final = "count"
T_FIRST: Final = "t_first"
T_LAST: Final = "t_last"
STATS: Final = ("min", "max", "first", "last")
LEVELS_S: Final = (1, 10, 60)
"""Widths of the cells kept beside each closed segment, s: each a whole multiple of the one
before, so a coarser cell is a union of finer ones."""
_BY_NAME: Final = {e.name: e for e in ELEMENTS}


def stat_column(element: str, stat: str) -> str:
    """The rollup column of one element's statistic: ``joint_position.0:max``."""
    return f"{element}:{stat}"


def cell_starts(cells: npt.NDArray[np.int64]) -> npt.NDArray[np.intp]:
    """Row index where each run of equal cell numbers begins (rows in time order)."""
    if cells.size == 0:
        return np.zeros(0, dtype=np.intp)
    changes = np.flatnonzero(np.diff(cells)) + 1
    return np.concatenate([np.zeros(1, dtype=np.intp), changes.astype(np.intp)])


def reduce_stat(
    element: Element, stat: str, values: np.ndarray, starts: npt.NDArray[np.intp]
) -> np.ndarray:
    """One statistic of ``values`` over the runs beginning at ``starts``: ``values`` are the
    frames' values, or finer cells' values of that same statistic (they compose)."""
    if starts.size == 0:
        return values[:0]
    if stat == "first":
        first: np.ndarray = values[starts]
        return first
    if stat == "last":
        last: np.ndarray = values[np.concatenate([starts[1:], [values.size]]) - 1]
        return last
    low = stat == "min"
    if element.kind == "float":
        return (np.fmin if low else np.fmax).reduceat(values, starts)
    if element.kind == "bool":
        folded = (np.minimum if low else np.maximum).reduceat(values.view(np.uint8), starts)
        return folded.astype(np.bool_)
    return (np.minimum if low else np.maximum).reduceat(values, starts)


def reduce_runs(
    element: Element, values: np.ndarray, starts: npt.NDArray[np.intp]
) -> dict[str, np.ndarray]:
    """min/max/first/last of ``values`` over the runs beginning at ``starts``."""
    if starts.size == 0:
        empty = values[:0]
        return {"min": empty, "max": empty, "first": empty, "last": empty}
    ends = np.concatenate([starts[1:], [values.size]]) - 1
    if element.kind == "float":
        low, high = np.fmin.reduceat(values, starts), np.fmax.reduceat(values, starts)
    elif element.kind == "bool":
        as_int = values.view(np.uint8)
        low = np.minimum.reduceat(as_int, starts).astype(np.bool_)
        high = np.maximum.reduceat(as_int, starts).astype(np.bool_)
    else:
        low, high = np.minimum.reduceat(values, starts), np.maximum.reduceat(values, starts)
    return {"min": low, "max": high, "first": values[starts], "last": values[ends]}


def rollup_schema(elements: list[Element] | tuple[Element, ...] = ELEMENTS) -> pa.Schema:
    fields = [
        pa.field(CELL, pa.int64()),
        pa.field(COUNT, pa.int32()),
        pa.field(T_FIRST, pa.float64()),
        pa.field(T_LAST, pa.float64()),
    ]
    for e in elements:
        fields.extend(pa.field(stat_column(e.name, s), e.arrow_type) for s in STATS)
    return pa.schema(fields)


def rollup_table(
    table: pa.Table, elements: list[Element] | tuple[Element, ...] = ELEMENTS
) -> pa.Table:
    """The per-second cells of a table of the recording's schema (sorted by time), for
    ``elements`` (default: all)."""
    t = time_seconds(table)
    cells = np.floor(t).astype(np.int64)
    starts = cell_starts(cells)
    ends = np.concatenate([starts[1:], [t.size]]).astype(np.intp) if t.size else starts
    arrays: list[pa.Array] = [
        pa.array(cells[starts]),
        pa.array((ends - starts).astype(np.int32)),
        pa.array(t[starts]),
        pa.array(t[ends - 1] if t.size else t),
    ]
    for e in elements:
        values = table.column(e.name).to_numpy(zero_copy_only=False)
        stats = reduce_runs(e, np.asarray(values), starts)
        arrays.extend(pa.array(stats[s], type=e.arrow_type) for s in STATS)
    return pa.Table.from_arrays(arrays, schema=rollup_schema(elements))


def element_of(column: str) -> Element:
    """The element of a rollup column (``joint_position.0:max``)."""
    return _BY_NAME[column.rpartition(":")[0]]


def coarsen(cells: pa.Table, width_s: int) -> pa.Table:
    """Cells of ``width_s`` seconds (aligned on the epoch) from finer cells of any of the
    rollup's columns, sorted by cell, each finer cell inside one coarser (``LEVELS_S``). A
    segment's first and last coarse cell hold only that segment's frames: two segments may
    each have a cell of the same number, in time order, which a query's buckets join."""
    if width_s == 1 or cells.num_rows == 0:
        return cells
    cell = cells.column(CELL).to_numpy()
    return _combine(cells, cell // width_s * width_s)


def join_split_cells(cells: pa.Table) -> pa.Table:
    """The cells of consecutive parts of one recording (in time order, ``rollup_table`` of
    each) as the whole's: a cell split between two parts (its number ending one part and
    starting the next) becomes one, exactly what its frames give (the statistics compose)."""
    if cells.num_rows == 0:
        return cells
    return _combine(cells, cells.column(CELL).to_numpy())


def _combine(cells: pa.Table, coarse: npt.NDArray[np.int64]) -> pa.Table:
    """One cell per run of equal ``coarse`` numbers (rows in time order), numbered by it."""
    starts = cell_starts(coarse)
    ends = np.concatenate([starts[1:], [coarse.size]]).astype(np.intp)
    arrays: list[pa.Array] = []
    for name in cells.column_names:
        values = np.asarray(cells.column(name).to_numpy(zero_copy_only=False))
        if name == CELL:
            arrays.append(pa.array(coarse[starts]))
        elif name == COUNT:
            arrays.append(pa.array(np.add.reduceat(values, starts).astype(np.int32)))
        elif name == T_FIRST:
            arrays.append(pa.array(values[starts]))
        elif name == T_LAST:
            arrays.append(pa.array(values[ends - 1]))
        else:
            element = element_of(name)
            stat = name.rpartition(":")[2]
            reduced = reduce_stat(element, stat, values, starts)
            arrays.append(pa.array(reduced, type=element.arrow_type))
    return pa.Table.from_arrays(arrays, schema=cells.schema)


def levels(cells: pa.Table, widths_s: Sequence[int] = LEVELS_S) -> list[pa.Table]:
    """The per-second ``cells`` and their coarser levels, each made from the one before."""
    out = [cells]
    for finer, width in itertools.pairwise(widths_s):
        assert width % finer == 0
        out.append(coarsen(out[-1], width))
    return out
