"""A journal becomes a segment a row group at a time, in a process of the closer's.

The streamed conversion equals converting the whole journal at once (frames, row groups, and
the cells of a second split between two row groups joined into one); a torn last batch is
left out; the closer converts in order, keeps a journal whose conversion fails and tries it
again, and converts what is left when it stops; its conversions run in a child process, which
says why one failed and does not outlive the process that started it."""

from __future__ import annotations

import array
import asyncio
import fcntl
import os
import sys
import termios
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from cobot_hmi.history import close_process, segments
from cobot_hmi.history.cells import read_cells_file
from cobot_hmi.history.close_process import JournalCloseError, close_in_child
from cobot_hmi.history.closer import JournalCloser
from cobot_hmi.history.rollup import LEVELS_S, coarsen, levels, rollup_table
from cobot_hmi.history.schema import items_to_batch
from cobot_hmi.history.segments import Segment
from process_support import all_ended, children
from test_history_storage import T0, Item, synthetic_items
from waiting import eventually

GROUP_ROWS = 128
"""Row groups this small in these tests (64 Ki in the product), so a journal of a few hundred
frames spans several and seconds are split between them."""


@pytest.fixture(autouse=True)
def small_row_groups(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(segments, "ROW_GROUP_ROWS", GROUP_ROWS)


def journal_of(root: Path, robot: str, items: list[Item]) -> Path:
    """``items`` as a closed journal, a batch of 37 frames at a time (batches and row groups
    do not line up)."""
    writer = segments.SegmentWriter(root, robot, segment_s=1e9)
    for offset in range(0, len(items), 37):
        writer.append(items_to_batch(items[offset : offset + 37]))
    path = writer.finish_journal()
    assert path is not None
    return path


def test_a_journal_becomes_the_segment_of_its_whole_table(tmp_path: Path) -> None:
    # 1000 frames at 7 ms: 7 s, its seconds split between row groups of 128 frames.
    items = synthetic_items(1000, start_s=T0 + 0.3, period_s=0.007)
    path = journal_of(tmp_path, "r", items)
    whole = segments.read_journal(path)
    segment = segments.close_journal(path, "r")
    assert segment is not None and not path.exists()
    assert segment.start_us == round((T0 + 0.3) * 1e6)
    assert segment.end_us == round((T0 + 0.3 + 999 * 0.007) * 1e6)
    parquet = pq.ParquetFile(segment.path)
    sizes = [parquet.metadata.row_group(i).num_rows for i in range(parquet.num_row_groups)]
    assert sizes == [GROUP_ROWS] * 7 + [1000 - 7 * GROUP_ROWS]
    assert parquet.read().equals(whole)
    # The cells: each second once, equal to the whole table's, at every width.
    expected = levels(rollup_table(whole))
    for width, level in zip(LEVELS_S, expected, strict=True):
        read = read_cells_file(segment.rollup_path, level.column_names, width)
        assert read is not None
        assert read.equals(level), width
    seconds = read_cells_file(segment.rollup_path, ["cell", "count"])
    assert seconds is not None
    cells = seconds.column("cell").to_pylist()
    assert cells == sorted(set(cells)) and sum(seconds.column("count").to_pylist()) == 1000
    assert coarsen(expected[0], 10).equals(expected[1])
    assert sorted(p.name for p in path.parent.iterdir()) == sorted(
        [segment.path.name, segment.rollup_path.name]
    )  # no temporary file left


def test_a_torn_last_batch_is_left_out(tmp_path: Path) -> None:
    items = synthetic_items(300)
    path = journal_of(tmp_path, "r", items)
    with path.open("r+b") as file:  # a crash in the middle of the last batch's write
        file.truncate(path.stat().st_size - 1000)
    segment = segments.close_journal(path, "r")
    assert segment is not None
    seqs = pq.read_table(segment.path, columns=["seq"]).column("seq").to_pylist()
    assert seqs == list(range(1, 8 * 37 + 1))  # eight whole batches of 37; the ninth torn


def test_a_journal_without_a_whole_batch_makes_no_segment(tmp_path: Path) -> None:
    path = journal_of(tmp_path, "r", synthetic_items(10))
    with path.open("r+b") as file:
        file.truncate(path.stat().st_size - 100)  # its only batch torn
    assert segments.close_journal(path, "r") is None
    assert not path.exists() and list(path.parent.iterdir()) == []


async def test_the_closer_keeps_a_journal_it_cannot_convert_and_tries_again(
    tmp_path: Path,
) -> None:
    closed: list[tuple[str, Segment | None]] = []
    first = journal_of(tmp_path, "a", synthetic_items(200))
    second = journal_of(tmp_path, "b", synthetic_items(100, start_s=T0 + 5))
    # The first journal's temporary Parquet cannot be created (a directory holds its name):
    # every write of it fails, as on a full disk.
    blocker = first.parent / f"{first.name}{segments.SEGMENT_SUFFIX}.tmp"
    blocker.mkdir()
    closer = JournalCloser(retry_s=0.05, on_closed=lambda robot, s: closed.append((robot, s)))
    closer.start()
    try:
        closer.submit("a", first)
        closer.submit("b", second)
        closer.submit("a", first)  # already waiting: not taken twice
        # The failing one is tried again and again; the journal stays whole meanwhile.
        await eventually(lambda: closer.errors >= 3)
        assert first.exists() and segments.read_journal(first).num_rows == 200
        assert closer.pending == 2 and closed == []
        assert closer.last_error is not None and first.name in closer.last_error
        blocker.rmdir()  # room again
        assert closer.wait_idle(30.0)
    finally:
        closer.stop()
    assert [robot for robot, _ in closed] == ["a", "b"]  # in the order handed over
    assert not first.exists() and not second.exists()
    for robot, rows in (("a", 200), ("b", 100)):
        (segment,) = segments.list_segments(tmp_path, robot)
        assert pq.read_metadata(segment.path).num_rows == rows


def test_stopping_converts_what_is_waiting(tmp_path: Path) -> None:
    journals = [
        journal_of(tmp_path, "r", synthetic_items(50, start_s=T0 + i * 10)) for i in range(3)
    ]
    closer = JournalCloser(retry_s=5.0)
    closer.start()
    for path in journals:
        closer.submit("r", path)
    closer.stop()
    assert segments.list_journals(tmp_path, "r") == []
    assert len(segments.list_segments(tmp_path, "r")) == 3


def test_the_closer_converts_in_a_process_of_its_own(tmp_path: Path) -> None:
    """The segment is made by a child (what its conversion allocated leaves with it): the
    closer's answer names the same segment a conversion here would have made."""
    journal = journal_of(tmp_path, "r", synthetic_items(300))
    made = close_in_child(journal, "r")
    assert made is not None and made.robot == "r"
    assert made == segments.list_segments(tmp_path, "r")[0]
    assert pq.read_metadata(made.path).num_rows == 300
    assert not journal.exists()
    # A journal without a complete frame makes no segment; the answer says so.
    empty = tmp_path / "r" / f"{int(T0 * 1e6) + 10**9}{segments.JOURNAL_SUFFIX}"
    empty.write_bytes(b"")
    assert close_in_child(empty, "r") is None


def test_a_failed_conversion_says_why_and_keeps_the_journal(tmp_path: Path) -> None:
    journal = journal_of(tmp_path, "r", synthetic_items(50))
    (journal.parent / f"{journal.name}{segments.SEGMENT_SUFFIX}.tmp").mkdir()
    with pytest.raises(JournalCloseError) as failed:
        close_in_child(journal, "r")
    assert "directory" in failed.value.reason  # the child's OSError, in its words
    assert segments.read_journal(journal).num_rows == 50


def test_a_child_whose_parent_is_already_gone_touches_nothing(tmp_path: Path) -> None:
    journal = journal_of(tmp_path, "r", synthetic_items(50))
    # This test's process is not the child's parent: it stops before converting.
    with pytest.raises(SystemExit) as ended:
        close_process.main(["--parent-pid", str(os.getpid() + 1), str(journal), "r"])
    assert ended.value.code == 3
    assert journal.exists() and segments.list_segments(tmp_path, "r") == []


async def test_a_conversion_ends_with_the_service_that_started_it(tmp_path: Path) -> None:
    """``kill -9`` of the service: its conversion under way does not run on beside the next
    start's recovery of the same journal. The conversion's temporary Parquet is a FIFO with a
    one-page buffer that this test holds open and never reads: once the child has written into
    it (past its start, converting), it waits in its write for as long as it lives."""
    journal = journal_of(tmp_path, "r", synthetic_items(200))
    parquet_tmp = journal.parent / f"{journal.name}{segments.SEGMENT_SUFFIX}.tmp"
    os.mkfifo(parquet_tmp)
    never_read = os.open(parquet_tmp, os.O_RDONLY | os.O_NONBLOCK)
    fcntl.fcntl(never_read, fcntl.F_SETPIPE_SZ, 4096)
    service = await asyncio.create_subprocess_exec(
        sys.executable,
        "-c",
        "import sys; from pathlib import Path; "
        "from cobot_hmi.history.close_process import close_in_child; "
        "close_in_child(Path(sys.argv[1]), 'r')",
        str(journal),
    )
    try:

        def converting() -> list[int]:
            """The service's child, once it has written Parquet into the FIFO."""
            waiting = array.array("i", [0])
            fcntl.ioctl(never_read, termios.FIONREAD, waiting)
            return children(service.pid) if waiting[0] > 0 else []

        await eventually(converting)
        (child,) = converting()
        service.kill()
        await service.wait()
        await all_ended([child])
    finally:
        if service.returncode is None:
            service.kill()
            await service.wait()
        os.close(never_read)  # a child still alive (the test failed) ends on a broken pipe
    assert journal.exists() and segments.list_segments(tmp_path, "r") == []
