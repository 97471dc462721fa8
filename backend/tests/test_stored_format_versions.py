"""Every stored format says its version: the previous version (files checked in under
``legacy/stored_formats/v1``, written by the code before formats carried one) is read as it was,
today's files carry their version, and a newer version is refused by name, the file untouched.

The fixtures (``legacy/stored_formats/README.md``) hold 30 frames of the golden T→O payloads
(``golden/t2o_*.hex``) 10 ms apart from 2025-12-01 00:00 UTC: the open segment's journal,
the same closed into a segment and its cells file, a users file and a Sparkplug spool; under
``legacy/stored_formats/v2``, the spool of the version before today's (no metric catalogue).
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from cobot_hmi.codec import decode_frame
from cobot_hmi.history import formats, segments
from cobot_hmi.history.cells import forget_cells, read_cells_file
from cobot_hmi.history.closer import JournalCloser
from cobot_hmi.history.journal_form import expand, records_to_journal_batch
from cobot_hmi.history.query import read_raw
from cobot_hmi.history.schema import SCHEMA, TIME, select_elements
from cobot_hmi.service.access.users import Role, UsersError, UsersFile
from cobot_hmi.sparkplug.buffer import DiskBuffer
from cobot_hmi.sparkplug.payload import parse_payload
from cobot_hmi.stored_format import FormatVersionError

V1 = Path(__file__).parent / "legacy" / "stored_formats" / "v1"
V2 = Path(__file__).parent / "legacy" / "stored_formats" / "v2"
GOLDEN = Path(__file__).parent / "golden"
START_S = 1_764_547_200.0
ROBOT = "m1013"
FRAMES = 30
SEGMENT_NAME = "1764547200000000-1764547200290000"


def _golden_records() -> list[tuple[int, float, object, int, bytes]]:
    """The fixtures' frames, made again with today's code."""
    names = ("t2o_all_zero.hex", "t2o_mid_motion.hex", "t2o_every_bit_extreme.hex")
    payloads = [bytes.fromhex("".join((GOLDEN / n).read_text().split())) for n in names]
    records: list[tuple[int, float, object, int, bytes]] = []
    for i in range(FRAMES):
        payload = payloads[i % 3]
        records.append((i, START_S + i * 0.01, decode_frame(payload), 1000 + i, payload))
    return records


def _expected() -> pa.Table:
    return pa.Table.from_batches([expand(records_to_journal_batch(_golden_records()))])


def _values(column: pa.ChunkedArray) -> list[object]:
    """A column's values, a NaN (the golden extremes have some) equal to a NaN."""
    return ["NaN" if isinstance(v, float) and math.isnan(v) else v for v in column.to_pylist()]


def _same_frames(table: pa.Table) -> None:
    expected = _expected()
    assert table.num_rows == FRAMES
    for name in SCHEMA.names:
        assert _values(table.column(name)) == _values(expected.column(name)), name


@pytest.fixture
def v1(tmp_path: Path) -> Path:
    """A copy of the previous version's files (a test may close or rewrite them)."""
    copy = tmp_path / "v1"
    shutil.copytree(V1, copy)
    return copy


def _journal(root: Path) -> Path:
    [(_, path)] = segments.list_journals(root / "history", ROBOT)
    return path


def _rewrite_stream(path: Path, metadata: dict[bytes, bytes]) -> None:
    """The journal at ``path`` again, its schema's metadata updated with ``metadata``."""
    with pa.OSFile(str(path), "rb") as source:
        table = pa.ipc.open_stream(source).read_all()
    schema = table.schema.with_metadata({**(table.schema.metadata or {}), **metadata})
    with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_stream(sink, schema) as writer:
        writer.write_table(table.cast(schema))


# --------------------------------------------------------------------- history journal


def test_a_journal_of_the_previous_version_reads_and_closes_as_today(v1: Path) -> None:
    path = _journal(v1)
    with pa.OSFile(str(path), "rb") as source:
        assert formats.FORMAT_VERSION_KEY not in (pa.ipc.open_stream(source).schema.metadata or {})
    _same_frames(segments.read_journal(path))
    segment = segments.close_journal(path, ROBOT)
    assert segment is not None and not path.exists()
    footer = pq.ParquetFile(segment.path).metadata.metadata
    assert footer[formats.FORMAT_VERSION_KEY] == b"2"
    _same_frames(segments.open_segment(segment.path).read())


def test_a_new_journal_carries_its_version_and_the_layouts(tmp_path: Path) -> None:
    writer = segments.SegmentWriter(tmp_path, ROBOT, 600.0)
    writer.append(records_to_journal_batch(_golden_records()))
    path = writer.finish_journal()
    assert path is not None
    with pa.OSFile(str(path), "rb") as source:
        metadata = pa.ipc.open_stream(source).schema.metadata
    assert metadata[formats.FORMAT_VERSION_KEY] == b"2"
    assert metadata[formats.LAYOUT_VERSION_KEY] == b"1"
    _same_frames(segments.read_journal(path))


def test_a_journal_of_a_newer_version_is_refused_by_name_and_kept(v1: Path) -> None:
    path = _journal(v1)
    _rewrite_stream(path, {formats.FORMAT_VERSION_KEY: b"3"})
    before = path.read_bytes()
    with pytest.raises(FormatVersionError, match=r"history journal version 3; .* 1 to 2"):
        segments.read_journal(path)
    with pytest.raises(FormatVersionError, match="history journal version 3"):
        segments.close_journal(path, ROBOT)
    assert segments.recover(v1 / "history", ROBOT) == []
    assert path.read_bytes() == before
    # A query leaves it out rather than failing the whole range.
    elements = select_elements(["robot_state"])
    assert read_raw(v1 / "history", ROBOT, elements, START_S, START_S + 1).num_rows == 0


def test_the_closer_leaves_a_newer_journal_as_it_is_and_does_not_try_again(v1: Path) -> None:
    path = _journal(v1)
    _rewrite_stream(path, {formats.FORMAT_VERSION_KEY: b"7"})
    closer = JournalCloser(retry_s=0.05)  # converts in a child process, as the service does
    closer.start()
    try:
        closer.submit(ROBOT, path)
        assert closer.wait_idle(60.0)
    finally:
        closer.stop()
    assert closer.refused == 1 and closer.errors == 0
    assert closer.last_error is not None and "history journal version 7" in closer.last_error
    assert path.exists()


def test_frames_of_a_newer_layout_are_refused_by_name(v1: Path) -> None:
    path = _journal(v1)
    _rewrite_stream(path, {formats.LAYOUT_VERSION_KEY: b"2"})
    with pytest.raises(FormatVersionError, match="recorded frames' layout version 2"):
        segments.read_journal(path)


# --------------------------------------------------------------------- history segment and cells


def _closed(root: Path, suffix: str) -> Path:
    return root / "history-closed" / ROBOT / f"{SEGMENT_NAME}{suffix}"


def test_a_segment_and_cells_of_the_previous_version_read_as_today(v1: Path) -> None:
    parquet = _closed(v1, segments.SEGMENT_SUFFIX)
    assert formats.FORMAT_VERSION_KEY not in (pq.ParquetFile(parquet).metadata.metadata or {})
    _same_frames(segments.open_segment(parquet).read())
    root = v1 / "history-closed"
    elements = select_elements(["robot_state", "joint_position"])
    raw = read_raw(root, ROBOT, elements, START_S, START_S + 1)
    assert raw.num_rows == FRAMES
    forget_cells()
    cells = read_cells_file(_closed(v1, segments.ROLLUP_SUFFIX), ["cell", "count"])
    assert cells is not None and cells.column("count").to_pylist() == [FRAMES]


def test_new_segments_and_cells_carry_their_version(tmp_path: Path) -> None:
    table = _expected()
    segment = segments.write_segment(table, tmp_path, ROBOT)
    assert segment is not None
    assert pq.ParquetFile(segment.path).metadata.metadata[formats.FORMAT_VERSION_KEY] == b"2"
    with pa.memory_map(str(segment.rollup_path)) as source:
        metadata = pa.ipc.open_file(source).schema.metadata
    assert metadata[formats.FORMAT_VERSION_KEY] == b"2"
    assert metadata[formats.LAYOUT_VERSION_KEY] == b"1"


def test_a_segment_of_a_newer_version_is_refused_by_name_and_left_out(v1: Path) -> None:
    parquet = _closed(v1, segments.SEGMENT_SUFFIX)
    table = pq.read_table(parquet)
    with pq.ParquetWriter(parquet, table.schema, store_schema=False) as writer:
        writer.write_table(table)
        writer.add_key_value_metadata({"cobot_hmi.format_version": "3"})
    with pytest.raises(FormatVersionError, match="history segment version 3"):
        segments.open_segment(parquet)
    elements = select_elements(["robot_state"])
    assert read_raw(v1 / "history-closed", ROBOT, elements, START_S, START_S + 1).num_rows == 0


def test_a_cells_file_of_a_newer_version_is_refused_by_name(v1: Path) -> None:
    path = _closed(v1, segments.ROLLUP_SUFFIX)
    with pa.memory_map(str(path)) as source:
        reader = pa.ipc.open_file(source)
        batches = [reader.get_batch(i) for i in range(reader.num_record_batches)]
        schema = reader.schema
    schema = schema.with_metadata({**(schema.metadata or {}), formats.FORMAT_VERSION_KEY: b"9"})
    with pa.OSFile(str(path), "wb") as sink, pa.ipc.new_file(sink, schema) as writer:
        for batch in batches:
            writer.write_batch(batch.replace_schema_metadata(schema.metadata))
    forget_cells()
    with pytest.raises(FormatVersionError, match="history cells file version 9"):
        read_cells_file(path, ["cell", "count"])


# --------------------------------------------------------------------- users file

V1_PASSWORD = "previous-format-pw"


def test_a_users_file_of_the_previous_version_reads_and_is_written_as_today(v1: Path) -> None:
    path = v1 / "users.json"
    assert "format_version" not in json.loads(path.read_text())
    users = UsersFile(path)
    alice = users.authenticate("alice", V1_PASSWORD)
    assert alice is not None and alice.role is Role.OPERATOR
    assert [t.name for t in users.tokens()] == ["kiosk-hall"]
    users.add("bob", Role.VIEWER, "a-new-password")
    document = json.loads(path.read_text())
    assert document["format_version"] == 2
    again = UsersFile(path)
    assert again.authenticate("alice", V1_PASSWORD) is not None
    assert [t.name for t in again.tokens()] == ["kiosk-hall"]


def test_a_users_file_of_a_newer_version_is_refused_by_name_the_last_table_kept(
    v1: Path,
) -> None:
    path = v1 / "users.json"
    users = UsersFile(path)
    assert users.authenticate("alice", V1_PASSWORD) is not None
    document = json.loads(path.read_text())
    document["format_version"] = 3
    path.write_text(json.dumps(document) + "\n")
    with pytest.raises(UsersError, match="users file version 3"):
        users.users()
    assert users.authenticate("alice", V1_PASSWORD) is not None  # the last good table
    with pytest.raises(UsersError, match="users file version 3"):
        UsersFile(path).users()


def test_the_fixtures_times_are_what_the_tests_assume() -> None:
    path = V1 / "history-closed" / ROBOT / f"{SEGMENT_NAME}{segments.SEGMENT_SUFFIX}"
    times = pq.read_table(path, columns=[TIME]).column(TIME).cast(pa.int64()).to_pylist()
    assert times[0] == int(START_S * 1e6) and len(times) == FRAMES


# --------------------------------------------------------------------- Sparkplug spool


def test_a_spool_segment_of_the_previous_version_replays_and_is_written_back_as_today(
    v1: Path,
) -> None:
    spool = v1 / "sparkplug-spool"
    old = spool / "0000000000.seg"
    assert not old.read_bytes().startswith(b"CHMISPL")
    buffer = DiskBuffer(spool, 1 << 20)
    assert buffer.records_buffered == 3
    [sealed] = buffer.sealed()
    records = buffer.read(sealed)
    assert [topic for topic, _ in records] == ["spBv1.0/cell/DDATA/edge/m1013"] * 3
    values = [parse_payload(payload).metrics[0].int_value for _, payload in records]
    assert values == [1, 2, 3]
    buffer.put_back(sealed, records[1:])  # a replay cut short: the rest stays, as today's
    assert sealed.read_bytes().startswith(b"CHMISPL\n\x03\x00")
    assert [parse_payload(p).metrics[0].int_value for _, p in buffer.read(sealed)] == [2, 3]
    assert DiskBuffer(spool, 1 << 20).records_buffered == 2


def test_a_spool_segment_of_version_2_replays_its_catalogue_unknown(tmp_path: Path) -> None:
    """Version 2 (``legacy/stored_formats/v2``, the mark and version, no metric catalogue): its
    records read as they were; the replay keeps only the layout's metrics of them
    (``test_sparkplug_spool_catalogue``)."""
    spool = tmp_path / "sparkplug-spool"
    shutil.copytree(V2 / "sparkplug-spool", spool)
    old = spool / "0000000000.seg"
    assert old.read_bytes().startswith(b"CHMISPL\n\x02\x00")
    buffer = DiskBuffer(spool, 1 << 20, {ROBOT: [(1005, "controlbox_di/DI 6", 11)]})
    assert buffer.records_buffered == 3
    [sealed] = buffer.sealed()
    segment = buffer.read_segment(sealed)
    assert (segment.version, segment.current, segment.catalogue) == (2, False, None)
    assert [parse_payload(p).metrics[0].boolean_value for _, p in segment.records] == [
        True,
        False,
        True,
    ]
    buffer.put_back(sealed, segment.records[1:])
    today = buffer.read_segment(sealed)
    assert (today.version, today.current, len(today.records)) == (3, True, 2)


def test_a_new_spool_segment_says_its_version(tmp_path: Path) -> None:
    buffer = DiskBuffer(tmp_path, 1 << 20)
    assert buffer.append("spBv1.0/cell/DDATA/edge/m1013", b"\x08\x01")
    [path] = sorted(tmp_path.glob("*.seg"))
    assert path.read_bytes()[:10] == b"CHMISPL\n\x03\x00"
    assert buffer.bytes_buffered == path.stat().st_size
    assert DiskBuffer(tmp_path, 1 << 20).read(path) == [
        ("spBv1.0/cell/DDATA/edge/m1013", b"\x08\x01")
    ]


def test_a_spool_segment_of_a_newer_version_is_refused_by_name_and_kept(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    newer = tmp_path / "0000000007.seg"
    newer.write_bytes(b"CHMISPL\n\x04\x00" + b"records of a format this build does not know")
    before = newer.read_bytes()
    with caplog.at_level("ERROR", logger="cobot_hmi.sparkplug.buffer"):
        buffer = DiskBuffer(tmp_path, 1 << 20)
    assert "Sparkplug spool segment version 4" in caplog.text
    assert buffer.records_buffered == 0 and buffer.sealed() == []
    assert buffer.append("spBv1.0/cell/DDATA/edge/m1013", b"\x08\x01")
    assert sorted(p.name for p in tmp_path.glob("*.seg")) == ["0000000007.seg", "0000000008.seg"]
    assert newer.read_bytes() == before
    with pytest.raises(FormatVersionError, match="Sparkplug spool segment version 4"):
        buffer.read(newer)
