"""Layer: service. The recorder: every frame of every robot into its recording
(``cobot_hmi.history``), off the hot path.

Each robot's frames reach the recorder as one of its frame consumers (``robots.frame_notifier``,
``FrameNotifier``: an O(1) append on the cyclic thread into a bounded queue of
``history_queue_frames``, the oldest dropped and counted when full: the cyclic connection never
waits). One thread of the recorder's own drains the queues every ``history_flush_s``, turns the
frames into one record batch per robot (numpy over the wire bytes, ``history.schema``) and appends
it to the robot's open segment; every ``history_segment_s`` it closes the segment's journal and
records on in a new one at once, while the closed journal is turned into Parquet in a short-lived
process of its own (``history.closer``: seconds of work for ten minutes at RPI 2 ms, which on this
thread held every robot's frames in their queues; in a process, the memory it takes leaves with it),
and retention (``history.retention``) runs. The work holds the GIL in short stretches (a second of
frames is converted in a few milliseconds; pyarrow's encoding and writing release it); the cyclic
connection does not depend on it for its timing (its receive times are the kernel's, its O→T packets
are sent by the C pump thread, which needs no GIL; bench/history compares the receive interval with
and without recording).

A disk that fills (or any write error: read-only, removed directory) pauses recording for every
robot with a ``recording`` event (state ``paused`` and the reason) on each robot's stream and
log, and raises each robot's built-in alarm ``recording_paused`` (high priority, so the banner
and the audible cue show it); so does free space under ``history_min_free_bytes``. The service
keeps running; frames meanwhile are counted as not recorded. Every ``RETRY_S`` the recorder
checks again (free space, and ``RESUME_PROBE_BYTES`` written and removed) and resumes at once
in new journals, the ones the pause left handed to the closer (event state ``recording``; the
alarm returns to normal, and waits for an acknowledgement if none came, as ISA-18.2 has it).
A restart that records again clears
an alarm a pause before it left active. A queue that overflowed is reported by an event (state
``overflow``, at most once per ``RETRY_S`` per robot) and in ``/metrics``.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import os
import shutil
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Final

import pyarrow as pa

from cobot_hmi.history import retention, segments
from cobot_hmi.history.closer import JournalCloser
from cobot_hmi.history.journal_form import records_to_journal_batch
from cobot_hmi.history.segments import Segment, SegmentWriter
from cobot_hmi.service.alarms.definitions import RECORDING_PAUSED
from cobot_hmi.service.extensions import MetricFamily
from cobot_hmi.service.robots.frame_notifier import FrameRecord, Registration, Runs

if TYPE_CHECKING:
    from cobot_hmi.service.recording.history_settings import HistorySettings
    from cobot_hmi.service.robots.robot import RobotRuntime

log = logging.getLogger(__name__)

RETRY_S: Final = 5.0
"""How often a paused recorder checks the disk again, and the least time between two overflow
events of one robot."""
RETENTION_INTERVAL_S: Final = 30.0
RESUME_PROBE_BYTES: Final = 1024 * 1024
"""A paused recorder resumes only once this much can be written under the history directory
(several seconds of frames of a robot at RPI 2 ms): a disk with a few kilobytes free would
pause it again at the next flush."""


@dataclass(slots=True)
class _Track:
    """One robot's recording state (owned by the recorder's thread)."""

    robot: RobotRuntime
    writer: SegmentWriter
    registration: Registration | None = None
    frames_recorded: int = 0
    frames_not_recorded: int = 0
    segments_closed: int = 0
    dropped_reported: int = 0
    overflow_reported_at: float = 0.0
    last_time_s: float | None = None
    """Receive time of the newest frame written to the journal."""


class Recorder:
    """Build with the recording's own settings, the directory it records into (``root``) and
    the robots; ``start`` on the web loop before the cyclic thread starts (so no frame is
    missed), ``stop`` after it stopped (the last frames are written and every open segment
    closed).

    A frame consumer (``robots.frame_notifier``) of every robot that runs on its own thread: each
    ``history_flush_s`` the thread takes every robot's queued frames (``on_frames``) and
    appends them to the robot's journal as one record batch sliced from the T→O payloads."""

    name: Final = "history"
    runs: Final = Runs.THREAD

    def __init__(
        self, settings: HistorySettings, root: Path, robots: Mapping[str, RobotRuntime]
    ) -> None:
        self.root = root
        self.settings = settings
        self.tracks = {
            name: _Track(robot, SegmentWriter(self.root, name, settings.history_segment_s))
            for name, robot in robots.items()
        }
        self.paused_reason: str | None = None
        """Why recording is paused (``None``: recording)."""
        self.write_errors = 0
        self.pauses = 0
        self.retention_deleted_segments = 0
        self.retention_freed_bytes = 0
        self.bytes_on_disk = 0
        self.cpu_seconds = 0.0
        """CPU time of the recorder's thread."""
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stopping = threading.Event()
        self._wake = threading.Event()
        """Set to run a cycle now (``flush``) or to stop."""
        self._cycles = threading.Condition()
        self._cycles_started = 0
        self._cycles_done = 0
        self._thread: threading.Thread | None = None
        self._next_retry = 0.0
        self._next_retention = 0.0
        self._next_space_check = 0.0
        self.closer = JournalCloser(retry_s=RETRY_S, on_closed=self._closed)

    # ------------------------------------------------------------ lifecycle (web loop)

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        for name, track in self.tracks.items():
            track.registration = track.robot.frames.add(self)
            track.dropped_reported = 0
            for _, path in segments.list_journals(self.root, name):  # left by a crash
                self.closer.submit(name, path)
            # Persisted from a pause before a restart: recording starts again (a disk still
            # full pauses it again at the first check).
            self._alarm_now(track.robot, paused=False, reason="recording resumed")
        self.closer.start()
        self._thread = threading.Thread(target=self._run, name="history recorder", daemon=True)
        self._thread.start()

    async def stop(self) -> None:
        self._stopping.set()
        self._wake.set()
        thread = self._thread
        if thread is not None:
            await asyncio.to_thread(thread.join)
        self._thread = None
        await asyncio.to_thread(self.closer.stop)  # every closed journal into its segment
        for track in self.tracks.values():
            if track.registration is not None:
                track.robot.frames.remove(track.registration)
                track.registration = None

    # ------------------------------------------------------------ the thread

    def _run(self) -> None:
        started = time.thread_time()
        try:
            while not self._stopping.is_set():
                self._wake.wait(self.settings.history_flush_s)
                self._wake.clear()
                if self._stopping.is_set():
                    break
                self._counted_cycle()
                self.cpu_seconds = time.thread_time() - started
            self._counted_cycle()
            self._close_all()
        finally:
            self.cpu_seconds = time.thread_time() - started

    def _counted_cycle(self) -> None:
        with self._cycles:
            self._cycles_started += 1
        try:
            self._guarded_cycle()
        finally:
            with self._cycles:
                self._cycles_done += 1
                self._cycles.notify_all()

    def flush(self, timeout_s: float) -> bool:
        """Write every frame received so far to the journals now, not at the next flush (an
        export reaching the present holds what the page showed); wait for it, at most
        ``timeout_s``. ``False``: not done in time, or the recorder is not running. Called off
        the event loop: it blocks."""
        thread = self._thread
        if thread is None or not thread.is_alive():
            return False
        with self._cycles:
            # A cycle started before this call may have taken its frames already: the next one.
            wanted = self._cycles_started + 1
            self._wake.set()
            return self._cycles.wait_for(lambda: self._cycles_done >= wanted, timeout_s)

    def _guarded_cycle(self) -> None:
        """A cycle; an unexpected error pauses recording (retried like a full disk) instead of
        ending the thread: recording never stops silently."""
        try:
            self._cycle()
        except Exception as error:
            log.exception("history recorder cycle failed")
            self.write_errors += 1
            for track in self.tracks.values():
                track.writer.abandon()
            self._pause(f"the recorder failed: {type(error).__name__}: {error}")

    def _cycle(self) -> None:
        now = time.monotonic()
        if now >= self._next_space_check:
            self._next_space_check = now + RETRY_S
            self._check_space()
        if self.paused_reason is not None and now >= self._next_retry:
            self._try_resume()
        for track in self.tracks.values():
            self._record(track, now)
        if self.paused_reason is None and now >= self._next_retention:
            self._next_retention = now + RETENTION_INTERVAL_S
            self._retention()

    @property
    def queue_frames(self) -> int:
        return self.settings.history_queue_frames

    def _record(self, track: _Track, now: float) -> None:
        registration = track.registration
        if registration is None:
            return
        dropped = registration.dropped
        if dropped > track.dropped_reported and now - track.overflow_reported_at >= RETRY_S:
            newly = dropped - track.dropped_reported
            track.dropped_reported = dropped
            track.overflow_reported_at = now
            self._event(
                track,
                "overflow",
                f"the recorder fell behind: {newly} frames not recorded",
                dropped=newly,
            )
        registration.deliver()  # on_frames, on this thread
        if self.paused_reason is not None:
            return
        try:
            if track.writer.due():
                self._hand_over(track)
        except (OSError, pa.ArrowException) as error:
            self._write_failed(track, error)

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        """One robot's frames since the last cycle into its journal (the recorder's thread)."""
        track = self.tracks[robot]
        if self.paused_reason is not None:
            track.frames_not_recorded += len(records)
            return
        try:
            track.writer.append(records_to_journal_batch(records))
        except (OSError, pa.ArrowException) as error:
            track.frames_not_recorded += len(records)
            self._write_failed(track, error)
            return
        except Exception as error:  # paused and retried, never a silent stop
            log.exception("history recorder: %s's frames not recorded", robot)
            track.frames_not_recorded += len(records)
            self.write_errors += 1
            track.writer.abandon()
            self._pause(f"the recorder failed: {type(error).__name__}: {error}")
            return
        track.frames_recorded += len(records)
        track.last_time_s = records[-1].received_at_s

    def _write_failed(self, track: _Track, error: OSError | pa.ArrowException) -> None:
        self.write_errors += 1
        track.writer.abandon()
        reason = error.strerror if isinstance(error, OSError) else None
        self._pause(f"cannot write {self.root}: {reason or error}")

    def _hand_over(self, track: _Track) -> None:
        """The open journal to the closer (it becomes a segment there); the next batch starts
        a new one."""
        path = track.writer.finish_journal()
        if path is not None:
            self.closer.submit(track.robot.name, path)

    def _closed(self, robot: str, segment: Segment | None) -> None:
        """A journal became a segment (on the closer's thread)."""
        track = self.tracks.get(robot)
        if track is not None and segment is not None:
            track.segments_closed += 1
        self._next_retention = 0.0

    def _close_all(self) -> None:
        for track in self.tracks.values():
            self._hand_over(track)

    def _check_space(self) -> None:
        minimum = self.settings.history_min_free_bytes
        if not minimum:
            return
        try:
            free = shutil.disk_usage(self._existing_parent()).free
        except OSError:
            return
        if free < minimum and self.paused_reason is None:
            self._pause(
                f"disk nearly full: {free // 1024**2} MiB free under {self.root} "
                f"(history_min_free_bytes {minimum // 1024**2} MiB)"
            )

    def _existing_parent(self) -> str:
        path = self.root
        while not path.exists() and path.parent != path:
            path = path.parent
        return str(path)

    def _try_resume(self) -> None:
        self._next_retry = time.monotonic() + RETRY_S
        minimum = self.settings.history_min_free_bytes
        try:
            if minimum and shutil.disk_usage(self._existing_parent()).free < minimum:
                return
            self.root.mkdir(parents=True, exist_ok=True)
            self._probe()
            journals = {name: segments.list_journals(self.root, name) for name in self.tracks}
        except OSError:
            return
        # The journals the pause left (their complete batches) become segments on the
        # closer's thread; recording goes on at once in new ones.
        for name, found in journals.items():
            for _, path in found:
                self.closer.submit(name, path)
        log.warning("history: recording resumed")
        self.paused_reason = None
        for track in self.tracks.values():
            self._event(track, "recording", "recording resumed")
            self._alarm(track, paused=False, reason="recording resumed")

    def _probe(self) -> None:
        """Write ``RESUME_PROBE_BYTES`` under the history directory and remove them
        (``OSError`` while they do not fit)."""
        probe = self.root / ".resume-probe"
        try:
            with probe.open("wb") as file:
                file.write(bytes(RESUME_PROBE_BYTES))
                file.flush()
                os.fsync(file.fileno())
        finally:
            with contextlib.suppress(OSError):
                probe.unlink()

    def _pause(self, reason: str) -> None:
        if self.paused_reason is not None:
            return
        log.warning("history: recording paused: %s", reason)
        self.paused_reason = reason
        self.pauses += 1
        self._next_retry = time.monotonic() + RETRY_S
        for track in self.tracks.values():
            track.writer.abandon()
            self._event(track, "paused", reason)
            self._alarm(track, paused=True, reason=f"recording paused: {reason}")

    def _retention(self) -> None:
        days = self.settings.history_retention_days
        try:
            result = retention.enforce(
                self.root,
                now_s=time.time(),
                max_age_s=days * 86400,
                max_bytes=self.settings.history_retention_bytes,
            )
        except OSError as error:
            log.warning("history retention failed: %s", error)
            return
        self.retention_deleted_segments += len(result.deleted)
        self.retention_freed_bytes += result.bytes_freed
        self.bytes_on_disk = result.bytes_kept

    def _event(self, track: _Track, state: str, reason: str, **extra: object) -> None:
        """A ``recording`` event on the robot's stream and log (from this thread)."""
        event: dict[str, object] = {
            "kind": "recording",
            "time": time.time(),
            "state": state,
            "reason": reason,
            **extra,
        }
        loop = self._loop
        if loop is None:
            return
        with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
            loop.call_soon_threadsafe(track.robot.publish_event, event)

    def _alarm(self, track: _Track, *, paused: bool, reason: str) -> None:
        """The robot's ``recording_paused`` alarm, on the web loop (from this thread): the
        alarm engine is the loop's."""
        loop = self._loop
        if loop is None:
            return
        with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
            loop.call_soon_threadsafe(
                functools.partial(self._alarm_now, track.robot, paused=paused, reason=reason)
            )

    @staticmethod
    def _alarm_now(robot: RobotRuntime, *, paused: bool, reason: str) -> None:
        now_s = time.time()
        robot.publish_events(
            robot.alarms.raised(RECORDING_PAUSED, active=paused, message=reason, now_s=now_s)
        )

    # ------------------------------------------------------------ /metrics

    def metric_families(self) -> list[MetricFamily]:
        tracks = list(self.tracks.values())

        def per_robot(value: str) -> list[tuple[dict[str, str], float]]:
            return [({"robot": t.robot.name}, float(getattr(t, value))) for t in tracks]

        return [
            ("history_recording", "gauge", "1 while recording, 0 while paused",
             [({}, 0.0 if self.paused_reason else 1.0)]),
            ("history_frames_recorded_total", "counter", "frames written to the recording",
             per_robot("frames_recorded")),
            ("history_frames_not_recorded_total", "counter",
             "frames received while recording was paused",
             per_robot("frames_not_recorded")),
            ("history_frames_dropped_total", "counter",
             "frames the recorder's queue dropped before it read them (overflow)",
             [({"robot": t.robot.name},
               float(t.registration.dropped if t.registration else t.dropped_reported))
              for t in tracks]),
            ("history_segments_closed_total", "counter", "segments closed into Parquet",
             per_robot("segments_closed")),
            ("history_write_errors_total", "counter", "failed writes (each pauses recording)",
             [({}, float(self.write_errors))]),
            ("history_journals_closing", "gauge",
             "closed journals waiting to become segments (or being converted)",
             [({}, float(self.closer.pending))]),
            ("history_journal_close_errors_total", "counter",
             "conversions of a closed journal that failed (each tried again; the journal kept)",
             [({}, float(self.closer.errors))]),
            ("history_pauses_total", "counter", "times recording paused",
             [({}, float(self.pauses))]),
            ("history_retention_deleted_segments_total", "counter",
             "segments deleted by retention (age or size)",
             [({}, float(self.retention_deleted_segments))]),
            ("history_bytes", "gauge", "bytes the recordings take on disk",
             [({}, float(self.bytes_on_disk))]),
            ("history_cpu_seconds_total", "counter", "CPU time of the recorder's thread",
             [({}, self.cpu_seconds)]),
        ]  # fmt: skip
