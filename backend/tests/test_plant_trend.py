"""The plant's trends (issue 41 "History"): a metric of a robot over hours is read from the row
groups that hold it (segments of version 2: series order, row-group keys) and equals a brute-force
read of every file by an independent reader (DuckDB); decimated, each bucket keeps its first,
lowest, highest and last row; the previous version's segments (checked in under
``legacy/stored_formats/plant_v1``, written by the recorder before version 2) read as they were
and are compacted into today's; a newer version is refused by name, left on disk."""

from __future__ import annotations

import logging
import random
import shutil
import time
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from cobot_hmi.plant import segments, trends
from cobot_hmi.plant.host import Sample
from cobot_hmi.plant.recorder import (
    COMPACT_AFTER_S,
    HOUR_MS,
    SEGMENT,
    MetricKey,
    PlantRecorder,
    Point,
)
from cobot_hmi.stored_format import FormatVersionError

PLANT_V1 = Path(__file__).parent / "legacy" / "stored_formats" / "plant_v1"
V1_START_MS = 1_764_547_200_000  # 2025-12-01 00:00 UTC, the fixture's first value
DEVICES = ["", "r1", "r2", "r3"]
METRICS = ["Joint/J1/Position", "Joint/J2/Position", "robot_state", "Cycle/Last"]


def _value(metric: str, rng: random.Random) -> object:
    if metric == "robot_state":
        return rng.choice(["STANDALONE_RUNNING", "STOPPED", None])
    return rng.choice([rng.uniform(-10, 10), rng.randint(0, 5), True])


def _record(directory: Path, start_ms: int, hours: int, seed: int) -> PlantRecorder:
    """``hours`` of values of 3 cells × 4 devices × 4 metrics, arriving out of order in flushes
    of the recorder's own writer (past hours compacted as it does)."""
    rng = random.Random(seed)
    samples = [
        Sample(
            start_ms + rng.randrange(hours * HOUR_MS),
            "area",
            f"cell-{rng.randrange(3)}",
            rng.choice(DEVICES),
            metric,
            _value(metric, rng),  # type: ignore[arg-type]
            rng.random() < 0.1,
        )
        for metric in rng.choices(METRICS, k=6000)
    ]
    recorder = PlantRecorder(directory)
    for batch in range(0, len(samples), 1000):
        recorder.add(samples[batch : batch + 1000])
        recorder.flush()
    return recorder


def _brute_force(directory: Path, key: MetricKey, start_ms: int, end_ms: int) -> list[Point]:
    """Every file read whole by DuckDB (no part is left that a segment holds: compacted)."""
    files = sorted(str(p) for p in directory.glob("*/*.parquet"))
    rows = duckdb.execute(
        f"SELECT time_ms, value, text, historical FROM read_parquet({files!r}) "
        'WHERE "group" = ? AND node = ? AND device = ? AND metric = ? '
        "AND time_ms BETWEEN ? AND ? ORDER BY time_ms",
        [key.group, key.node, key.device, key.metric, start_ms, end_ms],
    ).fetchall()
    return [Point(*row) for row in rows]


def _sorted(points: list[Point]) -> list[Point]:
    """Rows of the same millisecond in a stable order (either order is the trend's)."""
    return sorted(points, key=lambda p: (p.time_ms, repr(p)))


def test_a_trend_over_hours_equals_a_brute_force_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Small row groups, so that a series lies in a few of many (a plant's hour: ~100 of 32 Ki).
    monkeypatch.setattr(segments, "ROW_GROUP_ROWS", 64)
    segments.forget_indexes()
    now_ms = int(time.time() * 1000)
    # Six whole hours that ended an hour before this one began: each over for longer than the
    # recorder's COMPACT_AFTER_S whatever the minute now, so all compacted at once (six hours
    # up to this one's start failed in its first ten minutes: the last not compacted yet).
    assert COMPACT_AFTER_S * 1000 < HOUR_MS
    start_ms = now_ms - now_ms % HOUR_MS - 7 * HOUR_MS
    recorder = _record(tmp_path, start_ms, 6, seed=41)
    segment_files = sorted(tmp_path.glob(f"*/{SEGMENT}"))
    assert len(segment_files) == 6 and not list(tmp_path.glob("*/part-*"))
    for path in segment_files:
        metadata = pq.read_metadata(path)
        assert metadata.num_row_groups > 10
        assert metadata.metadata[segments.VERSION_KEY] == b"2"
    for node in ("cell-0", "cell-2"):
        for device in DEVICES:
            for metric in METRICS:
                key = MetricKey("area", node, device, metric)
                for low, high in (
                    (start_ms, start_ms + 6 * HOUR_MS),
                    (start_ms + 4321, start_ms + 2 * HOUR_MS + 99),
                ):
                    expected = _brute_force(tmp_path, key, low, high)
                    assert _sorted(recorder.trend(key, low, high)) == expected, key
    # A series is read from the row groups around it, not the whole hour.
    index = segments.file_index(segment_files[0])
    chosen = segments._row_groups(index, ("area", "cell-1", "r2", "robot_state"), 0, 2**62)
    assert 0 < len(chosen) <= 3 < index.groups
    # An unknown series reads nothing (no row group), a range outside the hours too.
    assert recorder.trend(MetricKey("area", "cell-7", "r1", "x"), start_ms, now_ms) == []
    assert recorder.trend(MetricKey("area", "cell-1", "r1", "robot_state"), 0, 1000) == []


def test_the_open_hours_parts_are_read_beside_the_segment(tmp_path: Path) -> None:
    now_ms = int(time.time() * 1000)
    recorder = PlantRecorder(tmp_path)
    key = MetricKey("area", "cell-1", "r1", "Joint/J1/Position")
    samples = [
        Sample(now_ms - 5000 + i, *("area", "cell-1", "r1", key.metric), float(i), False)
        for i in range(5)
    ]
    recorder.add(samples[:3])
    recorder.flush()
    recorder.add(samples[3:])
    recorder.flush()
    assert len(list(tmp_path.glob("*/part-*.parquet"))) == 2
    assert [p.value for p in recorder.trend(key, now_ms - 10_000, now_ms)] == [
        0.0,
        1.0,
        2.0,
        3.0,
        4.0,
    ]
    assert _brute_force(tmp_path, key, now_ms - 10_000, now_ms) == recorder.trend(
        key, now_ms - 10_000, now_ms
    )


def _decimated_by_hand(points: list[Point], start_ms: int, end_ms: int, buckets: int) -> set[Point]:
    span_ms = end_ms - start_ms + 1
    runs: dict[int, list[Point]] = {}
    for p in points:
        runs.setdefault(
            min(max((p.time_ms - start_ms) * buckets // span_ms, 0), buckets - 1), []
        ).append(p)
    kept: set[Point] = set()
    for run in runs.values():
        kept |= {run[0], run[-1]}
        numbers = [p for p in run if p.value is not None]
        if numbers:
            low = min(p.value for p in numbers if p.value is not None)
            high = max(p.value for p in numbers if p.value is not None)
            kept.add(next(p for p in numbers if p.value == low))
            kept.add(next(p for p in numbers if p.value == high))
    return kept


def test_decimation_keeps_each_buckets_first_lowest_highest_and_last() -> None:
    rng = random.Random(7)
    start_ms, end_ms = 1_000_000, 1_000_000 + 7 * 24 * HOUR_MS
    times = sorted(rng.sample(range(start_ms, end_ms), 20_000))
    # Numbers, and now and then a text (a state's words: no number).
    points = [
        Point(t, None, "STOPPED", False)
        if rng.random() < 0.05
        else Point(t, rng.gauss(0, 1), None, False)
        for t in times
    ]
    table = pa.table(
        {
            "time_ms": pa.array([p.time_ms for p in points], pa.int64()),
            "value": pa.array([p.value for p in points], pa.float64()),
            "text": pa.array([p.text for p in points], pa.string()),
            "historical": pa.array([False] * len(points)),
        }
    )
    for buckets in (1, 7, 500, 4999):
        found = trends.decimate(table, start_ms, end_ms, buckets)
        kept = [Point(*row.values()) for row in found.to_pylist()]
        assert kept == sorted(kept, key=lambda p: p.time_ms)
        assert set(kept) == _decimated_by_hand(points, start_ms, end_ms, buckets)
        assert len(kept) <= 4 * buckets
    # Few rows: all of them.
    assert trends.decimate(table.slice(0, 30), start_ms, end_ms, 10).num_rows == 30


def _fixture(tmp_path: Path) -> Path:
    copy = tmp_path / "plant-history"
    shutil.copytree(PLANT_V1, copy, ignore=shutil.ignore_patterns("README.md"))
    return copy


def test_the_previous_versions_segments_read_as_they_were(tmp_path: Path) -> None:
    directory = _fixture(tmp_path)
    for path in directory.glob(f"*/{SEGMENT}"):
        assert pq.read_metadata(path).metadata[segments.VERSION_KEY] == b"1"
    recorder = PlantRecorder(directory)
    end_ms = V1_START_MS + 2 * HOUR_MS
    r1 = recorder.trend(
        MetricKey("area-1", "cell-1", "r1", "Joint/J1/Position"), V1_START_MS, end_ms
    )
    assert [(p.time_ms - V1_START_MS, p.value) for p in r1] == [
        (i * 180_000, i * 0.5) for i in range(40)
    ]
    r2 = recorder.trend(
        MetricKey("area-1", "cell-1", "r2", "Joint/J1/Position"), V1_START_MS, end_ms
    )
    assert [(p.value, p.historical) for p in r2] == [(-float(i), i % 5 == 0) for i in range(40)]
    states = recorder.trend(MetricKey("area-1", "cell-1", "r1", "robot_state"), V1_START_MS, end_ms)
    assert [p.text for p in states] == [
        "STOPPED" if i % 8 == 0 else "STANDALONE_RUNNING" for i in range(0, 40, 4)
    ]
    hmi = recorder.trend(
        MetricKey("area-1", "cell-1", "", "Node Info/HMI URL"), V1_START_MS, end_ms
    )
    assert {p.text for p in hmi} == {"http://cell-1:8000/"} and len(hmi) == 10
    estop = recorder.trend(
        MetricKey("area-2", "cell-9", "r1", "Alarm/estop/Active"), V1_START_MS, end_ms
    )
    assert [p.value for p in estop] == [1.0 if i % 8 == 0 else 0.0 for i in range(0, 40, 4)]
    # A late part in a version 1 hour: compacted with it into a version 2 segment, nothing lost.
    late = Sample(V1_START_MS + 1, "area-1", "cell-1", "r1", "Joint/J1/Position", 99.0, True)
    recorder.add([late])
    recorder.flush()
    segment = directory / "2025-12-01T00" / SEGMENT
    assert pq.read_metadata(segment).metadata[segments.VERSION_KEY] == b"2"
    again = recorder.trend(
        MetricKey("area-1", "cell-1", "r1", "Joint/J1/Position"), V1_START_MS, end_ms
    )
    assert [(p.time_ms, p.value) for p in again] == [(r1[0].time_ms, 0.0), (late.time_ms, 99.0)] + [
        (p.time_ms, p.value) for p in r1[1:]
    ]


def test_a_newer_version_is_refused_by_name_and_left_on_disk(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    directory = _fixture(tmp_path)
    segment = directory / "2025-12-01T01" / SEGMENT
    table = pq.read_table(segment)
    future = table.replace_schema_metadata({segments.VERSION_KEY: b"3"})
    pq.write_table(future, segment)
    before = segment.read_bytes()
    with pytest.raises(FormatVersionError, match="plant history segment version 3"):
        segments.file_index(segment)
    recorder = PlantRecorder(directory)
    key = MetricKey("area-1", "cell-1", "r1", "Joint/J1/Position")
    with caplog.at_level(logging.WARNING):
        found = recorder.trend(key, V1_START_MS, V1_START_MS + 2 * HOUR_MS)
    assert [p.time_ms - V1_START_MS for p in found] == [i * 180_000 for i in range(20)]  # hour 0
    assert "plant history segment version 3" in caplog.text
    # A part that comes for that hour is not compacted over it.
    recorder.add(
        [Sample(V1_START_MS + HOUR_MS + 1, *("area-1", "cell-1", "r1", key.metric), 1.0, True)]
    )
    recorder.flush()
    assert segment.read_bytes() == before
