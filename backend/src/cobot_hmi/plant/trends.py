"""Layer: plant (a door above the service). A metric's trend as the plant's page asks for it:
the rows of the range from the history (``PlantRecorder.trend_table``), decimated on the server
to ``buckets`` equal spans of time when asked, as the cell's history does (docs/api.md
"History"): per bucket its first, lowest, highest and last value, in time order, so that every
peak stays drawn and a step stays where it was; a text value (a state's words) counts as a
first or last. A week of a value a second is 600 000 rows: decimated, at most 4 per bucket.

Imports ``recorder`` (``MetricKey``, ``PlantRecorder``).
"""

from __future__ import annotations

from typing import Final

import numpy as np
import pyarrow as pa

from cobot_hmi.plant.recorder import MetricKey, PlantRecorder, Point, points_of

MAX_BUCKETS: Final = 5000


def decimate(table: pa.Table, start_ms: int, end_ms: int, buckets: int) -> pa.Table:
    """``table`` (a trend's rows in time order) with, of each of ``buckets`` equal spans of
    ``[start_ms, end_ms]``, only its first, lowest, highest and last row (fewer when they
    coincide), in time order. A span without a number keeps its first and last row."""
    rows = table.num_rows
    if rows <= 4 * buckets:
        return table
    times = table["time_ms"].to_numpy()
    span_ms = max(end_ms - start_ms + 1, 1)
    bucket = np.clip((times - start_ms) * buckets // span_ms, 0, buckets - 1)
    # Rows are in time order, so each bucket is a run: its first and last row by the edges.
    edges = np.flatnonzero(np.diff(bucket)) + 1
    firsts = np.concatenate(([0], edges))
    lasts = np.concatenate((edges - 1, [rows - 1]))
    values = table["value"].to_numpy(zero_copy_only=False).astype(np.float64)
    missing = np.isnan(values)
    # The lowest (highest) row of each run: sorted by (bucket, value), the first of each run.
    lowest = np.lexsort((np.where(missing, np.inf, values), bucket))
    highest = np.lexsort((np.where(missing, np.inf, -values), bucket))
    runs = bucket[firsts]
    lows = lowest[np.searchsorted(bucket[lowest], runs)]
    highs = highest[np.searchsorted(bucket[highest], runs)]
    keep = np.concatenate((firsts, lasts, lows, highs))
    return table.take(pa.array(np.unique(keep)))


def trend(
    recorder: PlantRecorder,
    key: MetricKey,
    start_ms: int,
    end_ms: int,
    buckets: int | None = None,
) -> list[Point]:
    """One metric over ``[start_ms, end_ms]``: every row, or decimated to ``buckets``."""
    table = recorder.trend_table(key, start_ms, end_ms)
    if buckets is not None:
        table = decimate(table, start_ms, end_ms, buckets)
    return points_of(table)
