"""Layer: history storage. Imports only the history schema, numpy and pyarrow.

Per-second cells of a recording: for every element the min, max, first and last value of the
frames received in that whole second of the epoch, plus the cell's frame count and its first
and last receive times. A closed segment keeps its cells beside it (``*.cells.arrow``), so a
query of a long range reads one row per second instead of a hundred, and stays exact: a bucket
made of whole cells has exactly the min/max/first/last of its frames (``query``).

Floats use ``fmin``/``fmax``: a NaN frame does not hide the others' extremes; a cell of NaNs
only is NaN.
"""

from __future__ import annotations

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


def stat_column(element: str, stat: str) -> str:
    """The rollup column of one element's statistic: ``joint_position.0:max``."""
    return f"{element}:{stat}"


def cell_starts(cells: npt.NDArray[np.int64]) -> npt.NDArray[np.intp]:
    """Row index where each run of equal cell numbers begins (rows in time order)."""
    if cells.size == 0:
        return np.zeros(0, dtype=np.intp)
    changes = np.flatnonzero(np.diff(cells)) + 1
    return np.concatenate([np.zeros(1, dtype=np.intp), changes.astype(np.intp)])


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
