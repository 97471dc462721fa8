"""Plant trend benchmark (see bench/plant_trend). Prints the figure, its target and a baseline
measured in the same run.

1. Write: ``--days`` × 24 hours of the plant's history, each hour a compacted segment written by
   the recorder's own writer (``segments.write_segment``, what compaction calls): ``--robots``
   robots (10 a cell, 10 cells an area) × ``--metrics`` metrics, a value of each every
   ``--period-s`` on average (each series at its own moments). The baseline's copy holds the same
   rows in version 1's layout (time order, one row group per Mi rows: what the recorder wrote
   before version 2), its files saying version 1.
2. Query: the trend route's work (``trends.trend`` over the whole range, decimated to 1000
   buckets, the answer's models serialized to JSON) for ``--queries`` robots' metrics chosen at
   random: cold (every file's kept footer forgotten before each: as after a start, the files in
   the page cache) and warm (the same again). Target: every one < 1 s. Baseline: the same query
   over the version 1 copy (one query, cold).
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
import statistics
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from pydantic import TypeAdapter

from cobot_hmi.plant import segments, trends
from cobot_hmi.plant.recorder import SEGMENT, MetricKey, PlantRecorder, points_of
from cobot_hmi.plant.routes import TrendPoint

HOUR_MS = 3_600_000
BUCKETS = 1000
TARGET_S = 1.0
START_MS = 1_764_547_200_000  # 2025-12-01 00:00 UTC
ANSWER = TypeAdapter(list[TrendPoint])


def _series(robots: int, metrics: int) -> list[tuple[str, str, str, str]]:
    return [
        (f"area-{r // 100:02d}", f"cell-{r // 10:03d}", f"r{r % 10}", f"Metric/{m:03d}")
        for r in range(robots)
        for m in range(metrics)
    ]


def _hour(series: list[tuple[str, str, str, str]], period_s: float, seed: int) -> pa.Table:
    """An hour's rows (times from 0): each series a value every ``period_s`` on average."""
    rng = np.random.default_rng(seed)
    per = max(1, round(3600 / period_s))
    count = len(series) * per
    which = np.repeat(np.arange(len(series)), per)
    times = rng.integers(0, HOUR_MS, count, dtype=np.int64)
    columns = [pa.array([s[i] for s in series]).dictionary_encode() for i in range(4)]
    index = pa.array(which)
    return pa.table(
        {
            "time_ms": times,
            "group": columns[0].take(index).dictionary_decode(),
            "node": columns[1].take(index).dictionary_decode(),
            "device": columns[2].take(index).dictionary_decode(),
            "metric": columns[3].take(index).dictionary_decode(),
            "value": rng.normal(0, 1, count),
            "text": pa.nulls(count, pa.string()),
            "historical": np.zeros(count, dtype=bool),
        },
        schema=segments.SCHEMA,
    )


def _folder(root: Path, hour: int) -> Path:
    name = datetime.fromtimestamp((START_MS + hour * HOUR_MS) / 1000, UTC).strftime("%Y-%m-%dT%H")
    folder = root / name
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _write(root: Path, hours: int, hour: pa.Table) -> tuple[float, float, int]:
    """Both copies written; (seconds for today's, for version 1's, bytes of today's)."""
    today_s = before_s = 0.0
    size = 0
    v1_metadata = {segments.VERSION_KEY: b"1", segments.ABSORBED_KEY: b"[]"}
    by_time = hour.sort_by("time_ms")
    for h in range(hours):
        shift = pa.scalar(START_MS + h * HOUR_MS, pa.int64())
        table = hour.set_column(0, "time_ms", pa.compute.add(hour["time_ms"], shift))
        started = time.perf_counter()
        path = _folder(root / "v2", h) / SEGMENT
        segments.write_segment(path, table, [])
        today_s += time.perf_counter() - started
        size += path.stat().st_size
        old = by_time.set_column(0, "time_ms", pa.compute.add(by_time["time_ms"], shift))
        started = time.perf_counter()
        pq.write_table(old.replace_schema_metadata(v1_metadata), _folder(root / "v1", h) / SEGMENT)
        before_s += time.perf_counter() - started
        print(f"\r  hour {h + 1}/{hours}", end="", flush=True)
    print()
    return today_s, before_s, size


def _query(root: Path, key: MetricKey, hours: int) -> tuple[float, int, int]:
    """The route's work: (seconds, rows of the range, points answered)."""
    recorder = PlantRecorder(root)
    end_ms = START_MS + hours * HOUR_MS - 1
    started = time.perf_counter()
    table = recorder.trend_table(key, START_MS, end_ms)
    points = points_of(trends.decimate(table, START_MS, end_ms, BUCKETS))
    body = ANSWER.dump_json(
        [
            TrendPoint(time=p.time_ms / 1000, value=p.value, text=p.text, historical=p.historical)
            for p in points
        ]
    )
    elapsed = time.perf_counter() - started
    assert body.startswith(b"[")
    return elapsed, table.num_rows, len(points)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=float, default=7)
    parser.add_argument("--robots", type=int, default=500)
    parser.add_argument("--metrics", type=int, default=30)
    parser.add_argument("--period-s", type=float, default=30.0)
    parser.add_argument("--queries", type=int, default=5)
    parser.add_argument("--dir", type=Path, default=Path(tempfile.gettempdir()))
    args = parser.parse_args()
    hours = max(1, round(args.days * 24))
    series = _series(args.robots, args.metrics)
    hour = _hour(series, args.period_s, seed=41)
    print(
        f"plant trend: {hours} hours × {hour.num_rows:,} rows ({args.robots} robots × "
        f"{args.metrics} metrics, a value every {args.period_s:g} s); {os.cpu_count()} CPUs, "
        f"load average {os.getloadavg()[0]:.2f}"
    )
    root = Path(tempfile.mkdtemp(prefix="plant-trend-", dir=args.dir))
    try:
        today_s, before_s, size = _write(root, hours, hour)
        print(
            f"write: version 2 {today_s / hours:.2f} s an hour ({size / hours / 1e6:.1f} MB), "
            f"version 1 {before_s / hours:.2f} s an hour"
        )
        rng = random.Random(7)
        keys = [MetricKey(*rng.choice(series)) for _ in range(args.queries)]
        cold, warm = [], []
        for key in keys:
            segments.forget_indexes()
            elapsed, rows, points = _query(root / "v2", key, hours)
            cold.append(elapsed)
            warm.append(_query(root / "v2", key, hours)[0])
            print(
                f"  {key.node}/{key.device} {key.metric}: {rows:,} rows → {points} points, "
                f"cold {elapsed * 1000:.0f} ms, warm {warm[-1] * 1000:.0f} ms"
            )
        segments.forget_indexes()
        baseline_s, rows, _ = _query(root / "v1", keys[0], hours)
        worst = max(cold + warm)
        print(
            f"trend over {hours} h (target < {TARGET_S:.0f} s): cold median "
            f"{statistics.median(cold) * 1000:.0f} ms, max {max(cold) * 1000:.0f} ms; warm median "
            f"{statistics.median(warm) * 1000:.0f} ms, max {max(warm) * 1000:.0f} ms: "
            f"{'MET' if worst < TARGET_S else 'MISSED'}"
        )
        print(
            f"baseline (version 1's time order, the same query, cold): "
            f"{baseline_s * 1000:.0f} ms ({rows:,} rows); load average {os.getloadavg()[0]:.2f}"
        )
    finally:
        shutil.rmtree(root, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
