"""The recorder on a real full disk (a small tmpfs filled with a file, then freed): it pauses,
resumes once there is room without waiting for the paused journal to become a segment (that
happens on the closer's thread, here held back on purpose), and every frame it did not record
is one it counted as not recorded."""

from __future__ import annotations

from pathlib import Path

import pyarrow.parquet as pq

from cobot_hmi.history import segments
from service_support import emulator, eventually, running_service, service_settings
from tmpfs_support import fill, free, small_tmpfs


async def test_recording_resumes_at_once_while_the_paused_journal_waits(
    robot_host: str, plc_host: str, tmp_path: Path
) -> None:
    with small_tmpfs(tmp_path / "disk", 16) as disk:
        history = disk / "history"
        async with emulator(robot_host) as target:
            settings = service_settings(
                robot_host,
                target.tcp_port,
                plc_host,
                tmp_path / "state",
                history_dir=history,
                history_min_free_bytes=0,  # the full disk itself pauses it
                history_segment_s=3600.0,  # one journal until the disk fills
                history_flush_s=0.2,
            )
            async with running_service(settings) as hmi:
                recorder = hmi.service.recorder
                assert recorder is not None
                (name,) = hmi.service.robots
                track = recorder.tracks[name]
                await eventually(lambda: track.frames_recorded > 0)
                ((_, paused_journal),) = segments.list_journals(history, name)
                # Its conversion cannot write its Parquet (a directory holds the temporary
                # file's name) until the end of the test.
                blocker = paused_journal.with_name(
                    f"{paused_journal.name}{segments.SEGMENT_SUFFIX}.tmp"
                )
                blocker.mkdir()
                filler = fill(disk)
                await eventually(lambda: recorder.paused_reason is not None)
                assert "No space left on device" in (recorder.paused_reason or "")
                free(filler)
                await eventually(lambda: recorder.paused_reason is None)
                resumed_at = track.frames_recorded
                # Recording goes on in a new journal while the paused one still waits.
                await eventually(lambda: track.frames_recorded > resumed_at + 20)
                await eventually(lambda: recorder.closer.errors >= 1)
                journals = [path for _, path in segments.list_journals(history, name)]
                assert paused_journal in journals and len(journals) == 2
                assert segments.list_segments(history, name) == []
                blocker.rmdir()
                await eventually(lambda: not paused_journal.exists(), 60.0)
                await eventually(lambda: recorder.closer.pending == 0)
                (segment,) = segments.list_segments(history, name)
                ((_, new_journal),) = segments.list_journals(history, name)
                recorded = pq.read_table(segment.path, columns=["seq"]).column("seq").to_pylist()
                recorded += segments.read_journal(new_journal, ["seq"]).column("seq").to_pylist()
                not_recorded = track.frames_not_recorded
                dropped = track.registration.dropped if track.registration else 0
    # Every frame between the first and the last recorded one is recorded, or was counted as
    # not recorded while paused (the batch the full disk refused among them).
    assert recorded == sorted(recorded) and not_recorded > 0
    missing = recorded[-1] - recorded[0] + 1 - len(recorded)
    assert missing == not_recorded + dropped
