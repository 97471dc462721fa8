"""History storage on synthetic recordings: columns from the layout round trip to the wire bytes,
a torn journal keeps its complete batches, retention deletes the oldest first, decimated
min/max/first/last equal a brute-force computation over the raw rows (Hypothesis), each export
format read back by an independent reader (pyarrow, the ``mcap`` reader, Python's csv), each
carrying the frames' wire sequence numbers, and a recording made before the ``t2o_sequence``
column existed still read (the column null) by queries, exports and replay."""

from __future__ import annotations

import csv
import io
import math
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np
import orjson
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from cobot_hmi.codec import T2O_SIZE, Frame, decode_frame, encode_frame, zero_frame
from cobot_hmi.emulator.static_robot import standing_frame
from cobot_hmi.history import export, retention, segments
from cobot_hmi.history.cells import CELL_WIDTHS_KEY, read_cells_file
from cobot_hmi.history.query import (
    CELL_S,
    QueryError,
    QueryResult,
    bucket_grid,
    iter_raw,
    query,
    read_raw,
)
from cobot_hmi.history.recording import RecordingError, read_recording
from cobot_hmi.history.rollup import LEVELS_S
from cobot_hmi.history.schema import (
    ELEMENTS,
    SCHEMA,
    T2O_SEQUENCE,
    UnknownFieldError,
    column_arrays,
    columns_from_raw,
    items_to_batch,
    raw_from_columns,
    select_elements,
    time_seconds,
)
from cobot_hmi.history.times import TimeFormatError, parse_time
from cobot_hmi.layout import T2O_ASSEMBLY

Item = tuple[int, float, Frame, int]
"""A hub item: ``(seq, received_at, frame, t2o_sequence)``."""
T0 = 1_800_000_000.0  # a whole second, so cells line up with the synthetic rows below
WIRE0 = 0xFFFF_FF00
"""The first synthetic wire sequence number: 256 frames before the 32-bit wrap."""


def wire_number(i: int) -> int:
    """The ``i``-th synthetic frame's wire sequence number: one per packet, a packet the
    scanner did not deliver every 250th, across the 32-bit wrap."""
    return (WIRE0 + i + i // 250) & 0xFFFF_FFFF


def synthetic_items(
    n: int, start_s: float = T0, period_s: float = 0.01, seed: int = 1
) -> list[Item]:
    """``n`` hub items of frames whose joints, force, state and bits all change, their wire
    sequence numbers from ``wire_number``."""
    rng = np.random.default_rng(seed)
    base = standing_frame()
    items = []
    for i in range(n):
        frame = base._replace(
            joint_position=tuple(float(np.float32(v)) for v in rng.normal(0, 90, 6)),
            external_force=tuple(float(np.float32(v)) for v in rng.normal(0, 5, 3)),
            robot_state=int(rng.integers(0, 21)),
            servo_on=bool(rng.integers(0, 2)),
            controlbox_di=tuple(bool(b) for b in rng.integers(0, 2, 16)),
            bit_output_registers=tuple(bool(b) for b in rng.integers(0, 2, 64)),
        )
        # As a robot sends it: every REAL a float32 (decoded from its wire bytes).
        frame = decode_frame(encode_frame(frame))
        items.append((i + 1, start_s + i * period_s, frame, wire_number(i)))
    return items


def write_recording(root: Path, robot: str, items: list[Item], segment_rows: int) -> None:
    """``items`` as closed segments of ``segment_rows`` frames and an open journal after them."""
    writer = segments.SegmentWriter(root, robot, segment_s=1e9)
    for offset in range(0, len(items), segment_rows):
        writer.append(items_to_batch(items[offset : offset + segment_rows]))
        if offset + segment_rows < len(items):
            writer.close_segment()
    writer.abandon()  # the last part stays a journal, as while the service records


# --------------------------------------------------------------------------- schema


def test_columns_come_from_the_layout() -> None:
    count = sum(f.count for f in T2O_ASSEMBLY.fields)
    assert len(ELEMENTS) == count
    assert SCHEMA.names[:3] == ["time", "seq", "t2o_sequence"]
    assert SCHEMA.field(T2O_SEQUENCE).type == pa.uint32()
    assert "joint_position.0" in SCHEMA.names
    assert "robot_state" in SCHEMA.names
    assert SCHEMA.field("joint_torque.5").metadata[b"unit"] == "N·m".encode()
    assert SCHEMA.field("servo_on").type == pa.bool_()
    assert SCHEMA.field("robot_state").type == pa.uint8()
    assert SCHEMA.field("analog_input_type.1").type == pa.uint8()
    assert SCHEMA.field("tcp_position.2").type == pa.float32()


def test_batch_round_trips_to_the_wire_bytes() -> None:
    items = synthetic_items(50)
    batch = items_to_batch(items)
    raw = raw_from_columns(batch)
    for row, (_, _, frame, _) in zip(raw, items, strict=True):
        assert row.tobytes() == encode_frame(frame)
        assert decode_frame(row.tobytes()) == frame
    assert batch.column("seq").to_pylist() == list(range(1, 51))
    assert batch.column(T2O_SEQUENCE).to_pylist() == [wire_number(i) for i in range(50)]
    assert time_seconds(batch).tolist() == pytest.approx([item[1] for item in items], abs=1e-6)


def test_select_elements() -> None:
    assert [e.name for e in select_elements(["external_force"])] == [
        "external_force.0",
        "external_force.1",
        "external_force.2",
    ]
    assert [e.name for e in select_elements(["joint_position.2", "servo_on"])] == [
        "joint_position.2",
        "servo_on",
    ]
    assert len(select_elements(None)) == len(ELEMENTS)
    with pytest.raises(UnknownFieldError, match="joint_positon"):
        select_elements(["joint_positon"])


def test_times() -> None:
    assert parse_time("1800000000.5") == 1800000000.5
    assert parse_time("2027-01-15T08:00:00Z") == parse_time("2027-01-15T09:00:00+01:00")
    assert parse_time("2027-01-15T08:00:00") == parse_time("2027-01-15T08:00:00Z")
    for bad in ("yesterday", "nan", "2027-13-01T00:00:00Z"):
        with pytest.raises(TimeFormatError):
            parse_time(bad)


# --------------------------------------------------------------------------- segments


def test_torn_journal_keeps_its_complete_batches(tmp_path: Path) -> None:
    items = synthetic_items(300)
    writer = segments.SegmentWriter(tmp_path, "r", segment_s=1e9)
    for offset in range(0, 300, 100):
        writer.append(items_to_batch(items[offset : offset + 100]))
    journal = writer.journal_path
    assert journal is not None
    writer.abandon()
    size = journal.stat().st_size
    with journal.open("r+b") as file:  # a crash in the middle of the last batch's write
        file.truncate(size - 1000)
    made = segments.recover(tmp_path, "r")
    assert len(made) == 1
    assert segments.list_journals(tmp_path, "r") == []
    table = pq.read_table(made[0].path)
    assert table.column("seq").to_pylist() == list(range(1, 201))
    assert made[0].rollup_path.exists()


def test_journal_is_readable_while_open(tmp_path: Path) -> None:
    writer = segments.SegmentWriter(tmp_path, "r", segment_s=1e9)
    writer.append(items_to_batch(synthetic_items(10)))
    journal = writer.journal_path
    assert journal is not None
    # Another reader (a query, an export, a crash) sees the batch without a close.
    assert segments.read_journal(journal).num_rows == 10
    writer.abandon()


def test_journal_read_as_it_grows_equals_a_fresh_read(tmp_path: Path) -> None:
    items = synthetic_items(400)
    writer = segments.SegmentWriter(tmp_path, "r", segment_s=1e9)
    journal = None
    for offset in range(0, 400, 20):
        writer.append(items_to_batch(items[offset : offset + 20]))
        journal = writer.journal_path
        assert journal is not None
        # Each read parses only the new batches (kept per journal) and sees all of them.
        grown = segments.read_journal(journal, ["seq", "joint_position.0"])
        assert grown.column("seq").to_pylist() == list(range(1, offset + 21))
    assert journal is not None
    writer.abandon()
    segments.forget_journal(journal)
    fresh = segments.read_journal(journal)
    assert fresh.num_rows == 400
    assert fresh.equals(segments.read_journal(journal))
    # A torn tail is left out until it is complete.
    data = journal.read_bytes()
    journal.write_bytes(data[:-700])
    segments.forget_journal(journal)
    assert segments.read_journal(journal, ["seq"]).num_rows == 380
    journal.write_bytes(data)  # the same file grows: its last batch completes
    assert segments.read_journal(journal, ["seq"]).num_rows == 400


def test_cells_read_in_parts_equal_the_file(tmp_path: Path) -> None:
    items = synthetic_items(300, period_s=0.1)
    write_recording(tmp_path, "r", items, 150)  # a closed segment of 15 s, then a journal
    writer_segment = segments.list_segments(tmp_path, "r")[0]
    first = read_cells_file(writer_segment.rollup_path, ["cell", "robot_state:max"])
    both = read_cells_file(writer_segment.rollup_path, ["robot_state:max", "servo_on:min", "cell"])
    with pa.memory_map(str(writer_segment.rollup_path)) as source:
        whole = pa.Table.from_batches([pa.ipc.open_file(source).get_batch(0)])  # 1 s cells
        assert both is not None and first is not None
        assert both.equals(whole.select(["robot_state:max", "servo_on:min", "cell"]))
        assert first.equals(whole.select(["cell", "robot_state:max"]))
    assert both.num_rows == 15


def test_a_journal_closed_while_a_query_lists_is_read_once(tmp_path: Path) -> None:
    # The moment between a closed segment's rename and its journal's deletion: both on disk.
    items = synthetic_items(50)
    writer = segments.SegmentWriter(tmp_path, "r", segment_s=1e9)
    writer.append(items_to_batch(items))
    journal = writer.journal_path
    assert journal is not None
    writer.abandon()
    segments.write_segment(segments.read_journal(journal), journal.parent, "r")
    assert journal.exists() and segments.list_segments(tmp_path, "r")
    table = read_raw(tmp_path, "r", select_elements(["robot_state"]), T0 - 1, T0 + 10)
    assert table.column("seq").to_pylist() == list(range(1, 51))


# --------------------------------------------------------------------------- retention


def test_retention_deletes_the_oldest_first(tmp_path: Path) -> None:
    for robot, start in (("a", T0), ("b", T0 + 5)):
        write_recording(tmp_path, robot, synthetic_items(1000, start_s=start), 200)
    closed = {r: segments.list_segments(tmp_path, r) for r in ("a", "b")}
    assert [len(v) for v in closed.values()] == [4, 4]
    everything = sorted(
        (s for v in closed.values() for s in v), key=lambda s: (s.end_us, s.start_us)
    )
    sizes = {s.path: s.size_bytes() for s in everything}
    journals = sum(
        p.stat().st_size for r in ("a", "b") for _, p in segments.list_journals(tmp_path, r)
    )
    total = sum(sizes.values()) + journals
    # Size: just under the total minus the three oldest segments → exactly those three go.
    cap = total - sum(sizes[s.path] for s in everything[:3])
    result = retention.enforce(tmp_path, now_s=T0 + 100, max_age_s=1e9, max_bytes=cap)
    assert [s.path for s in result.deleted] == [s.path for s in everything[:3]]
    assert result.bytes_kept <= cap
    assert all(not s.path.exists() and not s.rollup_path.exists() for s in everything[:3])
    # Age: segments whose last frame is older than the bound, oldest first; journals stay.
    oldest_kept = everything[5]
    age = (T0 + 100) - (oldest_kept.end_us - 1) / 1e6
    result = retention.enforce(tmp_path, now_s=T0 + 100, max_age_s=age, max_bytes=10**12)
    assert [s.path for s in result.deleted] == [s.path for s in everything[3:5]]
    assert [s.path for s in segments.list_segments(tmp_path, "a")] + [
        s.path for s in segments.list_segments(tmp_path, "b")
    ] == sorted((s.path for s in everything[5:]), key=lambda p: (p.parent.name, p.name))
    assert all(segments.list_journals(tmp_path, r) for r in ("a", "b"))


# --------------------------------------------------------------------------- query


def brute_force(
    table: pa.Table, name: str, edges: list[tuple[float, float]]
) -> list[tuple[Any, ...]]:
    """Per bucket ``[lo, hi)``: (count, min, max, first, last) over the raw rows, plainly."""
    t = time_seconds(table).tolist()
    values = table.column(name).to_pylist()
    out = []
    for lo, hi in edges:
        inside = [v for ti, v in zip(t, values, strict=True) if lo <= ti < hi]
        if not inside:
            continue
        finite = [v for v in inside if not (isinstance(v, float) and math.isnan(v))]
        low = min(finite) if finite else math.nan
        high = max(finite) if finite else math.nan
        out.append((len(inside), low, high, inside[0], inside[-1]))
    return out


def answer_buckets(result: QueryResult, name: str) -> list[tuple[Any, ...]]:
    series = next(s for s in result.series if s.element.name == name)
    out = []
    assert result.count is not None
    for i, count in enumerate(result.count.tolist()):
        out.append(
            (
                count,
                *(series.stats[s][i].item() for s in ("min", "max", "first", "last")),
            )
        )
    return out


def f32(value: object) -> object:
    """A JSON value with every float as its float32, for comparing REALs as the wire has them."""
    if isinstance(value, float):
        return np.float32(value)
    if isinstance(value, list | tuple):
        return [f32(v) for v in value]
    if isinstance(value, dict):
        return {k: f32(v) for k, v in value.items()}
    return value


def same(a: list[tuple[Any, ...]], b: list[tuple[Any, ...]]) -> bool:
    def norm(row: tuple[Any, ...]) -> tuple[Any, ...]:
        return tuple("nan" if isinstance(v, float) and math.isnan(v) else v for v in row)

    return [norm(r) for r in a] == [norm(r) for r in b]


NAMES = ["joint_position.3", "robot_state", "servo_on", "bit_output_registers.7"]


HYPOTHESIS = settings(
    max_examples=30,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def check_decimation(
    root: Path,
    *,
    n: int,
    period_ms: float,
    segment_rows: int,
    start_frac: float,
    span_frac: float,
    points: int,
    nan_every: int,
    old_cells: bool = False,
) -> str:
    """Record synthetic frames, query, and compare every bucket with the brute force; the path
    the query took (raw, buckets from the raw rows, ``cells 1``/``cells 10``/``cells 60``:
    buckets from the cells of that width). ``old_cells``: the closed segments' cells files
    as written before the coarser levels existed (per-second cells only, no metadata)."""
    items = synthetic_items(n, start_s=T0 + 0.123, period_s=period_ms / 1000, seed=n)
    if nan_every:
        items = [
            (
                s,
                t,
                f._replace(joint_position=(*f.joint_position[:3], math.nan, *f.joint_position[4:])),
                w,
            )
            if s % nan_every == 0
            else (s, t, f, w)
            for s, t, f, w in items
        ]
    write_recording(root, "r", items, segment_rows)
    if old_cells:
        for segment in segments.list_segments(root, "r"):
            downgrade_cells(segment.rollup_path)
    duration = n * period_ms / 1000
    from_s = T0 + start_frac * duration
    to_s = from_s + max(span_frac * duration, 0.001)
    elements = select_elements(NAMES)
    result = query(root, "r", elements, from_s=from_s, to_s=to_s, points=points)
    width = (to_s - from_s) / points
    if result.mode == "raw":
        raw = read_raw(root, "r", elements, from_s, to_s)
        assert raw.num_rows <= points
        assert result.seq is not None
        assert result.seq.tolist() == raw.column("seq").to_pylist()
        inside = [item for item in items if from_s <= round(item[1] * 1e6) / 1e6 < to_s]
        assert result.seq.tolist() == [item[0] for item in inside]
        assert result.t2o_sequence == [item[3] for item in inside]
        return "raw"
    if width >= CELL_S:
        grid = bucket_grid(from_s, to_s, width)
        bucket_s, first_cell, end_cell = grid.bucket_s, grid.first_cell, grid.end_cell
        assert result.bucket_s == bucket_s
        assert result.cells_s == grid.cells_s and bucket_s % grid.cells_s == 0
        # Never fewer than 80 % of the buckets asked (LEVEL_SLACK).
        assert bucket_s <= max(1, math.ceil(width - 1e-9)) * 1.25
        edges = [(float(b), float(b + bucket_s)) for b in range(first_cell, end_cell, bucket_s)]
        table = read_raw(root, "r", elements, first_cell, end_cell)
    else:
        assert result.bucket_s == pytest.approx(width)
        edges = [(from_s + k * width, from_s + (k + 1) * width) for k in range(points)]
        edges[-1] = (edges[-1][0], to_s)
        table = read_raw(root, "r", elements, from_s, to_s)
    assert result.frames == table.num_rows
    for name in NAMES:
        assert same(answer_buckets(result, name), brute_force(table, name, edges)), name
    return f"cells {grid.cells_s}" if width >= CELL_S else "rows"


def downgrade_cells(path: Path) -> None:
    """Rewrite a cells file as before the coarser levels: its per-second batch only, no
    metadata."""
    with pa.memory_map(str(path)) as source:
        reader = pa.ipc.open_file(source)
        assert reader.schema.metadata[CELL_WIDTHS_KEY] == b"1,10,60"
        seconds = pa.Table.from_batches([reader.get_batch(0)]).replace_schema_metadata(None)
    with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_file(sink, seconds.schema) as writer:
        writer.write_table(seconds)


DECIMATION_CASES: dict[str, st.SearchStrategy[dict[str, Any]]] = {
    # Short ranges: the raw frames, or buckets reduced from them.
    "rows": st.fixed_dictionaries(
        {
            "n": st.integers(1, 900),
            "period_ms": st.sampled_from([1.0, 10.0, 37.0]),
            "segment_rows": st.integers(50, 400),
            "start_frac": st.floats(0, 1),
            "span_frac": st.floats(0.01, 1.2),
            "points": st.integers(1, 400),
            "nan_every": st.integers(0, 7),
        }
    ),
    # Long ranges: whole-second buckets from the per-second cells (closed segments and the
    # open journal), exactly what the raw rows give.
    "cells": st.fixed_dictionaries(
        {
            "n": st.integers(200, 900),
            "period_ms": st.sampled_from([100.0, 137.0, 250.0]),
            "segment_rows": st.integers(50, 400),
            "start_frac": st.floats(0, 0.5),
            "span_frac": st.floats(0.3, 1.2),
            "points": st.integers(1, 20),
            "nan_every": st.integers(0, 7),
        }
    ),
    # Days in miniature: buckets of tens of seconds to minutes from the 10 s and 1 min cells
    # (made from the per-second ones), or, for a recording older than those, from the
    # per-second cells coarsened at query time.
    "coarse cells": st.fixed_dictionaries(
        {
            "n": st.integers(150, 600),
            "period_ms": st.sampled_from([700.0, 1000.0, 2300.0]),
            "segment_rows": st.integers(30, 400),
            "start_frac": st.floats(0, 0.5),
            "span_frac": st.floats(0.3, 1.2),
            "points": st.integers(1, 12),
            "nan_every": st.integers(0, 7),
            "old_cells": st.booleans(),
        }
    ),
}


@pytest.mark.parametrize("case", list(DECIMATION_CASES))
@HYPOTHESIS
@given(data=st.data())
def test_decimation_equals_brute_force(
    tmp_path_factory: pytest.TempPathFactory, case: str, data: st.DataObject
) -> None:
    """Every bucket (or raw frame) of a query equals the brute force over the raw rows; a
    ``cells`` case's buckets (a second or more wide) come from the cells."""
    drawn = data.draw(DECIMATION_CASES[case], label=case)
    if case != "rows":
        span_s = drawn["span_frac"] * drawn["n"] * drawn["period_ms"] / 1000
        # Buckets of at least a cell; in the coarse case at least 36 s, which a 10 s or 1 min
        # level always serves (rounded up to them, they grow by at most a quarter).
        least_s = 36.0 if case == "coarse cells" else CELL_S
        drawn["points"] = max(1, min(drawn["points"], int(span_s / least_s)))
    path = check_decimation(tmp_path_factory.mktemp("history"), **drawn)
    if case == "cells":
        assert path.startswith("cells")
    if case == "coarse cells":
        assert path in ("cells 10", "cells 60")


@pytest.mark.parametrize(
    ("width_s", "bucket_s", "cells_s"),
    [(0.5, 1, 1), (3.6, 4, 1), (11.0, 11, 1), (13.0, 13, 1), (19.0, 20, 10), (61.0, 70, 10),
     (86.4, 90, 10), (131.0, 140, 10), (150.0, 180, 60), (604.8, 660, 60)],
)  # fmt: skip
def test_bucket_grid_picks_the_coarsest_cells_that_keep_the_points(
    width_s: float, bucket_s: int, cells_s: int
) -> None:
    grid = bucket_grid(T0, T0 + width_s * 1000, width_s)
    assert (grid.bucket_s, grid.cells_s) == (bucket_s, cells_s)
    assert grid.first_cell % bucket_s == 0 and grid.end_cell % bucket_s == 0


def test_coarse_cells_are_kept_beside_each_segment(tmp_path: Path) -> None:
    """Each closed segment's cells file holds a batch per width; each coarse level equals the
    per-second cells of the raw frames coarsened, and its frame counts add up."""
    items = synthetic_items(400, start_s=T0 + 3.3, period_s=0.7)
    write_recording(tmp_path, "r", items, 250)
    segment = segments.list_segments(tmp_path, "r")[0]
    columns = ["cell", "count", "t_first", "t_last", "joint_position.3:min", "servo_on:max",
               "robot_state:first", "external_force.1:last"]  # fmt: skip
    seconds = read_cells_file(segment.rollup_path, columns)
    assert seconds is not None
    frames = pq.read_table(segment.path)
    for width in LEVELS_S[1:]:
        level = read_cells_file(segment.rollup_path, columns, width)
        assert level is not None
        cells = level.column("cell").to_pylist()
        assert all(c % width == 0 for c in cells) and cells == sorted(set(cells))
        assert sum(level.column("count").to_pylist()) == frames.num_rows
        t = time_seconds(frames)
        for row, cell in enumerate(cells):
            inside = (t >= cell) & (t < cell + width)
            joint = frames.column("joint_position.3").to_numpy()[inside]
            assert level.column("joint_position.3:min")[row].as_py() == pytest.approx(joint.min())
            servo = frames.column("servo_on").to_numpy(zero_copy_only=False)[inside]
            assert level.column("servo_on:max")[row].as_py() == bool(servo.max())
            state = frames.column("robot_state").to_numpy()[inside]
            assert level.column("robot_state:first")[row].as_py() == state[0]
            force = frames.column("external_force.1").to_numpy()[inside]
            assert level.column("external_force.1:last")[row].as_py() == pytest.approx(force[-1])
    downgrade_cells(segment.rollup_path)
    fresh = segment.rollup_path.with_name("old.cells.arrow")  # not in the cache
    segment.rollup_path.rename(fresh)
    assert read_cells_file(fresh, columns, 60) is None
    old = read_cells_file(fresh, columns)
    assert old is not None and old.equals(seconds)


def test_a_journal_closed_while_a_range_is_read_is_read_as_its_segment(tmp_path: Path) -> None:
    """A streamed export lists the journal, reads the older segments, and meanwhile the
    recorder closes the journal: its frames come from the segment it became."""
    items = synthetic_items(300)
    write_recording(tmp_path, "r", items, 100)  # two closed segments, then a journal
    reading = iter_raw(tmp_path, "r", ["time", "seq"], T0, T0 + 10)
    seqs = next(reading).column("seq").to_pylist()  # listed, the first segment read
    [(_, journal)] = segments.list_journals(tmp_path, "r")
    assert segments.close_journal(journal, "r") is not None
    for table in reading:
        seqs += table.column("seq").to_pylist()
    assert seqs == list(range(1, 301))


def test_range_edges_follow_the_stored_times(tmp_path: Path) -> None:
    """A range starting between a frame's receive time and its stored (whole-microsecond)
    time: closed segment or journal, the frame is in or out the same way as by its stored
    time."""
    items = synthetic_items(30, start_s=T0 + 0.1234563)
    write_recording(tmp_path, "r", items, 10)  # two closed segments, then a journal
    elements = select_elements(["robot_state"])
    for first in (0, 10, 20):
        from_s = items[first][1]  # .1234563 s + k·10 ms: stored as .123456 s + k·10 ms
        result = query(tmp_path, "r", elements, from_s=from_s, to_s=T0 + 10, points=1000)
        assert result.seq is not None
        assert result.seq.tolist() == list(range(first + 2, 31))


def test_query_errors(tmp_path: Path) -> None:
    elements = select_elements(["joint_position"])
    with pytest.raises(QueryError) as error:
        query(tmp_path, "r", elements, from_s=T0, to_s=T0, points=10)
    assert error.value.field == "to"
    with pytest.raises(QueryError) as error:
        query(tmp_path, "r", elements, from_s=T0, to_s=T0 + 1, points=5001)
    assert error.value.field == "points"
    empty = query(tmp_path, "nobody", elements, from_s=T0, to_s=T0 + 86400, points=1000)
    assert empty.mode == "raw" and empty.frames == 0 and empty.t.size == 0


# --------------------------------------------------------------------------- exports


@pytest.fixture
def recorded(tmp_path: Path) -> tuple[Path, list[Item]]:
    items = synthetic_items(700, start_s=T0 + 0.5)
    write_recording(tmp_path, "cell-1", items, 300)
    return tmp_path, items


def _export(
    root: Path, fmt: str, fields: list[str] | None, events: list[dict[str, Any]] | None = None
) -> bytes:
    elements = select_elements(fields)
    tables = export.tables(root, "cell-1", elements, from_s=T0, to_s=T0 + 100, fmt=fmt)
    return b"".join(export.export(tables, "cell-1", elements, fmt, events or []))


def test_parquet_export_read_by_pyarrow(recorded: tuple[Path, list[Item]]) -> None:
    root, items = recorded
    table = pq.read_table(pa.BufferReader(_export(root, "parquet", None)))
    # Columns named as the screen labels them (J 1 is joint_position.J1), the API key beside.
    assert table.schema.names == [*SCHEMA.names[:3], *(e.export_name for e in ELEMENTS)]
    assert table.schema.field("time").type == pa.timestamp("us", tz="UTC")
    assert table.schema.metadata[b"robot"] == b"cell-1"
    meta = table.schema.field("joint_position.J1").metadata
    assert (meta[b"unit"], meta[b"label"], meta[b"key"]) == (b"degree", b"J 1", b"joint_position.0")
    assert table.num_rows == len(items)
    for row, (_, _, frame, _) in zip(raw_from_columns(table), items, strict=True):
        assert row.tobytes() == encode_frame(frame)
    assert table.column(T2O_SEQUENCE).to_pylist() == [item[3] for item in items]


def test_parquet_export_read_by_duckdb(recorded: tuple[Path, list[Item]], tmp_path: Path) -> None:
    """An independent reader (DuckDB's own Parquet reader, no Arrow involved)."""
    import duckdb

    root, items = recorded
    path = tmp_path / "export.parquet"
    path.write_bytes(_export(root, "parquet", ["joint_position", "servo_on", "robot_state"]))
    with duckdb.connect() as db:
        rows = db.execute(
            'SELECT epoch_us("time"), seq, t2o_sequence, "joint_position.J4", servo_on, '
            f"robot_state FROM read_parquet('{path}') ORDER BY seq"
        ).fetchall()
        types = dict(
            db.execute(
                f"SELECT column_name, column_type FROM (DESCRIBE SELECT * FROM '{path}')"
            ).fetchall()
        )
    assert types["time"] == "TIMESTAMP WITH TIME ZONE"
    assert types["joint_position.J4"] == "FLOAT"
    assert types["servo_on"] == "BOOLEAN"
    assert types["robot_state"] == "UTINYINT"
    assert types["t2o_sequence"] == "UINTEGER"
    assert len(rows) == len(items)
    for (time_us, seq, wire, joint, servo, state), (i_seq, t, frame, i_wire) in zip(
        rows, items, strict=True
    ):
        assert time_us == round(t * 1e6)
        assert seq == i_seq
        assert wire == i_wire
        assert np.float32(joint) == np.float32(frame.joint_position[3])
        assert servo == frame.servo_on
        assert state == frame.robot_state


def test_csv_export_read_by_python_csv(recorded: tuple[Path, list[Item]]) -> None:
    root, items = recorded
    text = _export(root, "csv", ["joint_position", "servo_on", "robot_state"]).decode()
    rows = list(csv.reader(io.StringIO(text)))
    header = rows[0]
    assert header[:4] == ["time", "seq", "t2o_sequence", "joint_position.J1 [degree]"]
    assert header[-2:] == ["servo_on", "robot_state"]
    assert len(rows) - 1 == len(items)
    for row, (seq, t, frame, wire) in zip(rows[1:], items, strict=True):
        moment = datetime.fromisoformat(row[0])
        assert row[0].endswith("Z")
        assert moment.timestamp() == pytest.approx(t, abs=1e-6)
        assert int(row[1]) == seq
        assert int(row[2]) == wire
        # Each REAL written as the shortest text that reads back as the same float32.
        assert [np.float32(v) for v in row[3:9]] == [np.float32(v) for v in frame.joint_position]
        assert row[9] == ("true" if frame.servo_on else "false")
        assert int(row[10]) == frame.robot_state


def test_mcap_export_read_by_the_mcap_reader(recorded: tuple[Path, list[Item]]) -> None:
    root, items = recorded
    events = [
        {"kind": "robot_state", "time": T0 + 2.0, "robot": "cell-1", "from": 13, "to": 3},
        {"kind": "flag", "time": T0 + 4.0, "robot": "cell-1", "flag": "servo_on", "value": False},
    ]
    data = _export(root, "mcap", ["joint_position.2", "external_force"], events)
    reader = make_reader(io.BytesIO(data))
    summary = reader.get_summary()
    assert summary is not None
    topics = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
    assert set(topics) == {"/cell-1/frames", "/cell-1/events"}
    frame_schema = topics["/cell-1/frames"]
    assert frame_schema.encoding == "jsonschema"
    schema = orjson.loads(frame_schema.data)
    # A field asked for in part is exported whole, and every exported field is described.
    assert schema["properties"]["joint_position"]["maxItems"] == 6
    assert "degree" in schema["properties"]["joint_position"]["description"]
    # The columns as the CSV and Parquet name them, and where a message holds each.
    [record] = list(reader.iter_metadata())
    assert record.name == "cobot_hmi.columns"
    assert record.metadata["joint_position.J3"] == "joint_position[2] [degree]"
    assert record.metadata["external_force.X"] == "external_force[0] [N]"
    assert schema["properties"]["t2o_sequence"]["type"] == ["integer", "null"]
    frames, sequences, seen_events = [], [], []
    for _, channel, message in reader.iter_messages(log_time_order=True):
        if channel.topic == "/cell-1/frames":
            frames.append(orjson.loads(message.data))
            sequences.append(message.sequence)
        else:
            seen_events.append(orjson.loads(message.data))
    assert seen_events == events
    assert len(frames) == len(items)
    # MCAP's own message sequence: the wire number (both uint32).
    assert sequences == [item[3] for item in items]
    for message, (seq, t, frame, wire) in zip(frames, items, strict=True):
        assert message["seq"] == seq
        assert message["t2o_sequence"] == wire
        assert message["time"] == pytest.approx(t, abs=1e-6)
        # REALs as the shortest text of their float32: the same float32 read back.
        assert f32(message["joint_position"]) == f32(frame.joint_position)
        assert f32(message["external_force"]) == f32(frame.external_force)
        assert set(message) == {
            "time",
            "seq",
            "t2o_sequence",
            "joint_position",
            "external_force",
        }


def test_export_streams_one_segment_at_a_time(recorded: tuple[Path, list[Item]]) -> None:
    root, _ = recorded
    elements = select_elements(None)
    tables = export.tables(root, "cell-1", elements, from_s=T0, to_s=T0 + 100, fmt="parquet")
    chunks = list(export.export(tables, "cell-1", elements, "parquet"))
    # Three parts on disk (two closed segments and the journal): a chunk each, then the footer.
    assert len([c for c in chunks if c]) >= 3


def test_filename_names_robot_and_range() -> None:
    name = export.export_filename("cell-1", parse_time("2027-01-15T08:00:00Z"), T0, "mcap")
    assert name.startswith("cell-1_20270115T080000Z_")
    assert name.endswith(".mcap")


# --------------------------------------------------------------------------- replay files


def test_recordings_read_back_for_replay(recorded: tuple[Path, list[Item]], tmp_path: Path) -> None:
    root, items = recorded
    for fmt in ("parquet", "mcap"):
        path = tmp_path / f"x.{fmt}"
        path.write_bytes(_export(root, fmt, None))
        recording = read_recording(path)
        assert len(recording) == len(items)
        assert recording.robot == "cell-1"
        for row, (_, _, frame, _) in zip(recording.raw, items, strict=True):
            assert row.tobytes() == encode_frame(frame), fmt
    bad = tmp_path / "x.txt"
    bad.write_bytes(b"time,seq\n")
    with pytest.raises(RecordingError, match="neither Parquet nor MCAP"):
        read_recording(bad)


def test_zero_frame_columns_are_zero() -> None:
    batch = items_to_batch([(1, T0, zero_frame(), 0)])
    assert raw_from_columns(batch)[0].tobytes() == bytes(284)


# --------------------------------------------------------------------------- cobot-hmi export


def test_export_verb(
    recorded: tuple[Path, list[Item]], tmp_path_factory: pytest.TempPathFactory
) -> None:
    from cobot_hmi.cli import main

    root, items = recorded
    state = tmp_path_factory.mktemp("state")
    (state / "history").symlink_to(root)
    out = tmp_path_factory.mktemp("out") / "x.csv"
    base = ["export", "--state-dir", str(state), "--from", str(T0), "--to", str(T0 + 100)]
    assert main([*base, "--fields", "robot_state", "-o", str(out)]) == 0
    rows = list(csv.reader(io.StringIO(out.read_text())))
    assert rows[0] == ["time", "seq", "t2o_sequence", "robot_state"]
    assert [int(r[2]) for r in rows[1:]] == [item[3] for item in items]
    assert [int(r[3]) for r in rows[1:]] == [item[2].robot_state for item in items]
    # The only robot recorded is the default; a name that is not recorded is refused.
    assert main([*base, "--robot", "nobody", "-o", str(out)]) == 2
    assert main([*base, "--fields", "nothing", "-o", str(out)]) == 2
    assert main(["export", "--state-dir", str(state), "--from", "2", "--to", "1"]) == 2


# --------------------------------------------------------------------------- an upgrade


OLD_SCHEMA = SCHEMA.remove(SCHEMA.get_field_index(T2O_SEQUENCE))
"""The recording's schema before the wire sequence number was kept."""


def write_old_recording(root: Path, robot: str, items: list[Item], segment_rows: int) -> None:
    """``items`` as a service before ``t2o_sequence`` left them: closed segments of
    ``segment_rows`` frames, then a journal (its crash left it open), all without the column."""
    directory = segments.robot_dir(root, robot)
    directory.mkdir(parents=True, exist_ok=True)
    parts = [items[o : o + segment_rows] for o in range(0, len(items), segment_rows)]
    for part in parts[:-1]:
        table = pa.Table.from_batches([items_to_batch(part)]).drop_columns([T2O_SEQUENCE])
        assert table.schema.equals(OLD_SCHEMA)
        segments.write_segment(table, directory, robot)
    last = pa.Table.from_batches([items_to_batch(parts[-1])]).drop_columns([T2O_SEQUENCE])
    start_us = round(parts[-1][0][1] * 1e6)
    with (
        pa.OSFile(str(directory / f"{start_us}{segments.JOURNAL_SUFFIX}"), "wb") as sink,
        pa.ipc.new_stream(sink, OLD_SCHEMA) as journal,
    ):
        for batch in last.to_batches(max_chunksize=50):
            journal.write_batch(batch)


def test_a_recording_made_before_the_wire_number_stays_readable(tmp_path: Path) -> None:
    """Segments and a journal without ``t2o_sequence``, then the upgraded service's own: a
    query, every export and replay read both, the old rows' wire number null (CSV: empty;
    MCAP: null, the message sequence the service's counter), the values unchanged; the old
    journal closes into a segment that keeps every frame."""
    items = synthetic_items(700, start_s=T0 + 0.5)
    old, new = items[:450], items[450:]
    write_old_recording(tmp_path, "cell-1", old, 200)  # two segments, a journal of 50 frames
    wires: list[int | None] = [None] * len(old) + [item[3] for item in new]

    def check(root: Path) -> None:
        elements = select_elements(["robot_state", "joint_position"])
        raw = query(root, "cell-1", elements, from_s=T0, to_s=T0 + 100, points=5000)
        assert raw.mode == "raw" and raw.seq is not None
        assert raw.seq.tolist() == [item[0] for item in items]
        assert raw.t2o_sequence == wires
        state = next(x for x in raw.series if x.element.name == "robot_state")
        assert state.values is not None
        assert state.values.tolist() == [item[2].robot_state for item in items]
        buckets = query(root, "cell-1", elements, from_s=T0, to_s=T0 + 8, points=4)
        assert buckets.mode == "buckets" and buckets.frames == len(items)
        table = pq.read_table(pa.BufferReader(_export(root, "parquet", None)))
        # The export names each element as the screen labels it (joint_position.J1).
        assert table.schema.names == export.export_schema("cell-1", ELEMENTS).names
        assert table.column(T2O_SEQUENCE).to_pylist() == wires
        for row, (_, _, frame, _) in zip(raw_from_columns(table), items, strict=True):
            assert row.tobytes() == encode_frame(frame)
        rows = list(csv.reader(io.StringIO(_export(root, "csv", ["robot_state"]).decode())))
        assert [r[2] for r in rows[1:]] == ["" if w is None else str(w) for w in wires]
        reader = make_reader(io.BytesIO(_export(root, "mcap", ["robot_state"])))
        messages = [
            (orjson.loads(m.data), m.sequence)
            for _, channel, m in reader.iter_messages(log_time_order=True)
            if channel.topic == "/cell-1/frames"
        ]
        assert [m["t2o_sequence"] for m, _ in messages] == wires
        assert [sequence for _, sequence in messages] == [
            item[0] if w is None else w for item, w in zip(items, wires, strict=True)
        ]
        replay = tmp_path / "replay.parquet"
        replay.write_bytes(_export(root, "parquet", None))
        assert len(read_recording(replay)) == len(items)

    # The upgraded service: its journal after the old one (a restart records in a new one).
    writer = segments.SegmentWriter(tmp_path, "cell-1", segment_s=1e9)
    writer.append(items_to_batch(new))
    writer.abandon()
    assert len(segments.list_journals(tmp_path, "cell-1")) == 2
    check(tmp_path)
    # Its start closes the old journal (and its own, left by a crash) into segments.
    made = segments.recover(tmp_path, "cell-1")
    assert len(made) == 2 and not segments.list_journals(tmp_path, "cell-1")
    assert pq.read_table(made[0].path).column(T2O_SEQUENCE).null_count == 50
    check(tmp_path)


def test_history_storage_imports_only_the_layout_and_the_codec() -> None:
    """The layering (docs/architecture.md): the service, the command line and the emulator use
    ``cobot_hmi.history``, so it must not import any of them (nor ``enip`` or the scanner); the
    pure ``stored_format`` below the layout is shared with every stored format."""
    import ast

    import cobot_hmi.history

    allowed = (
        "cobot_hmi.layout",
        "cobot_hmi.codec",
        "cobot_hmi.generated",
        "cobot_hmi.history",
        "cobot_hmi.stored_format",
    )
    package = Path(cobot_hmi.history.__file__).parent
    for source in sorted(package.glob("*.py")):
        tree = ast.parse(source.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            for name in names:
                if name.startswith("cobot_hmi"):
                    assert name.startswith(allowed), f"{source.name} imports {name}"


async def test_export_events_are_read_a_batch_at_a_time(tmp_path: Path) -> None:
    """The MCAP export's events from the real event log, a few at a time (times shared by
    several events, other robots' and outside the range left out): the same as one read."""
    from cobot_hmi.service.storage.history_events import events_between, iter_events
    from cobot_hmi.service.storage.store import Store

    database = tmp_path / "hmi.db"
    store = Store(database)
    await store.open()
    try:
        for i in range(40):
            for robot in ("cell-1", "other"):
                store.log_event(
                    {
                        "kind": "flag",
                        "time": T0 + i // 3,
                        "robot": robot,
                        "flag": "servo_on",
                        "value": i % 2 == 0,
                        "n": i,
                    }
                )
        await store.flush_events()
    finally:
        await store.close()
    whole = events_between(database, "cell-1", T0 + 1, T0 + 12)
    assert [e["n"] for e in whole] == list(range(3, 36))
    for batch_rows in (1, 4, 33, 1000):
        batched = list(iter_events(database, "cell-1", T0 + 1, T0 + 12, batch_rows=batch_rows))
        assert batched == whole, batch_rows
    assert list(iter_events(tmp_path / "none.db", "cell-1", T0, T0 + 1)) == []


@pytest.mark.parametrize("frames", [0, 1, 7, 8, 9, 100])
def test_column_arrays_are_the_columns_sliced_one_by_one(frames: int) -> None:
    """The recorder's gather per kind of column gives every column exactly as slicing it out
    of the byte matrix alone does (random bytes: every bit, NaNs and all)."""
    raw = np.random.default_rng(frames).integers(0, 256, (frames, T2O_SIZE), dtype=np.uint8)
    sliced = columns_from_raw(raw)
    arrays = column_arrays(raw)
    assert len(arrays) == len(ELEMENTS)
    for element, array in zip(ELEMENTS, arrays, strict=True):
        assert array.type == element.arrow_type, element.name
        expected = sliced[element.name].astype(array.type.to_pandas_dtype())
        assert array.to_numpy(zero_copy_only=False).tobytes() == expected.tobytes(), element.name
