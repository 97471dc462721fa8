"""The open segment's journal in its form of payloads (``history.journal_form``): a batch of
payloads expands to exactly the element columns slicing the same bytes gives (Hypothesis, any
bytes, any slice), the recorder's journal reads back as the recording's schema while it grows
and after a crash tore its last batch, and it closes into the same segment a journal of element
columns (an earlier version's) closes into."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_hmi.codec import T2O_SIZE, decode_frame, encode_frame
from cobot_hmi.emulator.static_robot import standing_frame
from cobot_hmi.history import segments
from cobot_hmi.history.journal_form import (
    JOURNAL_SCHEMA,
    T2O_PAYLOAD,
    expand,
    is_journal_form,
    records_to_journal_batch,
)
from cobot_hmi.history.schema import SCHEMA, raw_to_batch

T0 = 1_800_000_000.0
Record = tuple[int, float, object, int, bytes]


def records(n: int, seed: int = 1) -> list[Record]:
    """``n`` frame records as the notifier hands them to the recorder, their joints, state
    and bits changing."""
    rng = np.random.default_rng(seed)
    out: list[Record] = []
    for i in range(n):
        frame = standing_frame()._replace(
            joint_position=tuple(float(np.float32(v)) for v in rng.normal(0, 90, 6)),
            robot_state=int(rng.integers(0, 21)),
            controlbox_di=tuple(bool(b) for b in rng.integers(0, 2, 16)),
        )
        payload = encode_frame(frame)
        out.append((i + 1, T0 + i * 0.01, decode_frame(payload), 7_000 + i, payload))
    return out


def same_columns(a: pa.RecordBatch | pa.Table, b: pa.RecordBatch | pa.Table) -> bool:
    """Equal schemas and equal values, a NaN equal to the same NaN (compared as bits)."""
    if not a.schema.equals(b.schema, check_metadata=True) or a.num_rows != b.num_rows:
        return False
    for x, y in zip(a.columns, b.columns, strict=True):
        left = x.to_numpy(zero_copy_only=False)
        right = y.to_numpy(zero_copy_only=False)
        if left.dtype == np.float32:
            left, right = left.view(np.uint32), right.view(np.uint32)
        if not np.array_equal(left, right):
            return False
    return True


@settings(max_examples=60, deadline=None)
@given(
    blob=st.binary(min_size=T2O_SIZE * 5, max_size=T2O_SIZE * 5),
    start=st.integers(0, 4),
    length=st.integers(0, 5),
)
def test_a_batch_of_payloads_expands_to_the_columns_of_its_bytes(
    blob: bytes, start: int, length: int
) -> None:
    payloads = [blob[i * T2O_SIZE : (i + 1) * T2O_SIZE] for i in range(5)]
    recs: list[Record] = [(i + 1, T0 + i / 100, None, i, p) for i, p in enumerate(payloads)]
    batch = records_to_journal_batch(recs)
    assert batch.schema.equals(JOURNAL_SCHEMA) and is_journal_form(batch.schema)
    raw = np.frombuffer(blob, dtype=np.uint8).reshape(5, T2O_SIZE)
    whole = raw_to_batch(range(1, 6), [r[1] for r in recs], raw, range(5))
    assert same_columns(expand(batch), whole)
    part = batch.slice(start, length)  # an offset into the payloads' buffer
    assert same_columns(expand(part), whole.slice(start, length))


def test_a_payload_of_another_size_is_refused() -> None:
    recs: list[Record] = [(1, T0, None, 0, bytes(T2O_SIZE)), (2, T0, None, 1, bytes(10))]
    with pytest.raises(ValueError, match=f"each must be {T2O_SIZE}"):
        records_to_journal_batch(recs)


def test_the_recorders_journal_reads_as_the_recording_while_it_grows_and_when_torn(
    tmp_path: Path,
) -> None:
    recs = records(250)
    writer = segments.SegmentWriter(tmp_path, "r1", segment_s=1e9)
    expected = raw_to_batch(
        [r[0] for r in recs],
        [r[1] for r in recs],
        np.frombuffer(b"".join(r[4] for r in recs), dtype=np.uint8).reshape(-1, T2O_SIZE),
        [r[3] for r in recs],
    )
    for offset in range(0, 200, 100):
        writer.append(records_to_journal_batch(recs[offset : offset + 100]))
    path = writer.journal_path
    assert path is not None
    assert T2O_PAYLOAD in pa.ipc.open_stream(path.read_bytes()).schema.names
    table = segments.read_journal(path)
    assert table.schema.equals(SCHEMA, check_metadata=True)
    assert same_columns(table, pa.Table.from_batches([expected.slice(0, 200)]))
    writer.append(records_to_journal_batch(recs[200:]))  # read again: only the new batch
    assert segments.read_journal(path, ["seq"]).column("seq").to_pylist() == list(range(1, 251))
    writer.abandon()
    with path.open("r+b") as file:  # a crash in the middle of the last batch
        file.truncate(path.stat().st_size - 100)
    segments.forget_journal(path)
    torn = segments.read_journal(path)
    assert same_columns(torn, pa.Table.from_batches([expected.slice(0, 200)]))


def test_both_forms_close_into_the_same_segment(tmp_path: Path) -> None:
    recs = records(300, seed=3)
    columns = [
        raw_to_batch(
            [r[0] for r in part],
            [r[1] for r in part],
            np.frombuffer(b"".join(r[4] for r in part), dtype=np.uint8).reshape(-1, T2O_SIZE),
            [r[3] for r in part],
        )
        for part in (recs[:120], recs[120:])
    ]
    closed = []
    for name, batches in (
        ("payloads", [records_to_journal_batch(recs[:120]), records_to_journal_batch(recs[120:])]),
        ("columns", columns),  # a journal an earlier version wrote
    ):
        writer = segments.SegmentWriter(tmp_path / name, "r1", segment_s=1e9)
        for batch in batches:
            writer.append(batch)
        segment = writer.close_segment()
        assert segment is not None
        closed.append(segment)
    tables = [pq.read_table(segment.path) for segment in closed]
    assert tables[0].num_rows == 300
    assert same_columns(tables[0], tables[1])
