"""Layer: service (Sparkplug). Data kept on disk while the broker is away, bounded.

Records (topic and payload bytes) are appended to segment files in a directory of the state
directory; the oldest segment is deleted whole when the total would exceed ``max_bytes`` (its
records counted as dropped). After the reconnect the edge node reads the sealed segments oldest
first, publishes their records (marked historical) and deletes each segment once it went out;
what could not go out yet (another disconnect, a robot not born yet) is written back. Segments
left by a previous run are replayed too. Writes go through the page cache (no fsync per record): a
power cut may lose the newest records, never corrupts older ones (a torn last record is cut).

Each segment starts with its format's version (``SPOOL_FORMAT``): an 8-byte mark and a 16-bit
version, then the records. Version 1, written before segments carried one, is the records
alone (no record starts with the mark: its topic would be 18,499 bytes long) and is read as it
is; a segment of a newer version is refused by name, left on disk as it is and never replayed.

Imports only ``stored_format`` of the project.
"""

from __future__ import annotations

import contextlib
import logging
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Final

from cobot_hmi.stored_format import FormatVersionError, StoredFormat

log = logging.getLogger(__name__)

SPOOL_FORMAT: Final = StoredFormat("Sparkplug spool segment", 2)
_MARK: Final = b"CHMISPL\n"
_FILE_HEADER: Final = struct.Struct("<8sH")
"""The mark and the format's version at the start of a segment."""

_HEADER: Final = struct.Struct("<HI")
"""Topic length, payload length."""
_MIN_SEGMENT_BYTES: Final = 64 * 1024
_SEGMENTS: Final = 16
"""About this many segments make up the bound: dropping one loses 1/16 of the buffer."""

Record = tuple[str, bytes]


def _file_header() -> bytes:
    return _FILE_HEADER.pack(_MARK, SPOOL_FORMAT.version)


def _records_start(data: bytes, where: Path) -> int:
    """Where a segment's records start (after its header; 0 in a version 1 segment), its version
    checked (``FormatVersionError`` for a newer one)."""
    if not data.startswith(_MARK):
        return 0
    if len(data) < _FILE_HEADER.size:
        return len(data)  # a header torn by a crash: no records
    _, version = _FILE_HEADER.unpack_from(data)
    SPOOL_FORMAT.read_version(version, where)
    return _FILE_HEADER.size


def _records(data: bytes, offset: int = 0) -> Iterator[Record]:
    while offset + _HEADER.size <= len(data):
        topic_len, payload_len = _HEADER.unpack_from(data, offset)
        start = offset + _HEADER.size
        end = start + topic_len + payload_len
        if end > len(data):
            return  # a record torn by a crash mid-write
        yield data[start : start + topic_len].decode(), data[start + topic_len : end]
        offset = end


def encode_record(topic: str, payload: bytes) -> bytes:
    topic_bytes = topic.encode()
    return _HEADER.pack(len(topic_bytes), len(payload)) + topic_bytes + payload


class DiskBuffer:
    """Segments ``NNNNNNNNNN.seg`` in ``directory``; at most ``max_bytes`` on disk."""

    def __init__(self, directory: Path, max_bytes: int) -> None:
        self.directory = directory
        self.max_bytes = max_bytes
        self.segment_bytes = max(_MIN_SEGMENT_BYTES, max_bytes // _SEGMENTS)
        self._segments: list[tuple[Path, int, int]] = []
        """(path, bytes, records) oldest first; the last one is being appended to."""
        self.records_buffered = 0
        self.bytes_buffered = 0
        self.records_dropped = 0
        self.records_written = 0
        self._next_number = 0
        if max_bytes > 0:
            self._scan()

    @property
    def enabled(self) -> bool:
        return self.max_bytes > 0

    def _scan(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            for path in sorted(self.directory.glob("*.seg")):
                try:
                    data = path.read_bytes()
                    number = int(path.stem)
                except (OSError, ValueError):
                    continue
                self._next_number = max(self._next_number, number + 1)
                try:
                    start = _records_start(data, path)
                except FormatVersionError as error:
                    log.error("Sparkplug buffer: left as it is, not replayed: %s", error)
                    continue
                count = sum(1 for _ in _records(data, start))
                self._segments.append((path, len(data), count))
                self.records_buffered += count
                self.bytes_buffered += len(data)
        if self._segments:
            log.info(
                "Sparkplug buffer: %d records from a previous run in %s",
                self.records_buffered,
                self.directory,
            )

    def _new_segment(self) -> Path:
        path = self.directory / f"{self._next_number:010d}.seg"
        self._next_number += 1
        self._segments.append((path, 0, 0))
        return path

    def append(self, topic: str, payload: bytes) -> bool:
        """Keep one record; ``False`` when buffering is off or the disk refused it."""
        if not self.enabled:
            self.records_dropped += 1
            return False
        record = encode_record(topic, payload)
        if not self._segments or self._segments[-1][1] + len(record) > self.segment_bytes:
            self._new_segment()
        if self._segments[-1][1] == 0:
            record = _file_header() + record  # a new segment starts with its version
        while self.bytes_buffered + len(record) > self.max_bytes and len(self._segments) > 1:
            self._drop_oldest()
        path, size, count = self._segments[-1]
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            with path.open("ab") as file:
                file.write(record)
        except OSError as error:
            log.warning("Sparkplug buffer: cannot write %s: %s", path, error)
            self.records_dropped += 1
            return False
        self._segments[-1] = (path, size + len(record), count + 1)
        self.records_buffered += 1
        self.bytes_buffered += len(record)
        self.records_written += 1
        return True

    def _drop_oldest(self) -> None:
        path, size, count = self._segments.pop(0)
        with contextlib.suppress(OSError):
            path.unlink()
        self.records_buffered -= count
        self.bytes_buffered -= size
        self.records_dropped += count
        log.warning("Sparkplug buffer full: dropped the oldest %d records", count)

    def sealed(self) -> list[Path]:
        """The segments that new records no longer go to (a fresh one takes them from now
        on), oldest first: what a replay may read, ``finish`` or ``put_back``."""
        if self._segments and self._segments[-1][1] > 0:
            self._new_segment()
        return [path for path, _, _ in self._segments[:-1]]

    def read(self, path: Path) -> list[Record]:
        """A segment's records (none if it cannot be read)."""
        try:
            data = path.read_bytes()
        except OSError:
            return []
        return list(_records(data, _records_start(data, path)))

    def finish(self, path: Path) -> None:
        """The segment went out: delete it."""
        for i, (candidate, size, count) in enumerate(self._segments):
            if candidate == path:
                del self._segments[i]
                self.records_buffered -= count
                self.bytes_buffered -= size
                break
        with contextlib.suppress(OSError):
            path.unlink()

    def put_back(self, path: Path, remaining: list[Record]) -> None:
        """Replay stopped part-way: keep what did not go out, still the oldest."""
        data = _file_header() + b"".join(encode_record(t, payload) for t, payload in remaining)
        for i, (candidate, size, count) in enumerate(self._segments):
            if candidate == path:
                try:
                    path.write_bytes(data)
                except OSError as error:
                    log.warning("Sparkplug buffer: cannot rewrite %s: %s", path, error)
                self._segments[i] = (path, len(data), len(remaining))
                self.records_buffered += len(remaining) - count
                self.bytes_buffered += len(data) - size
                return
