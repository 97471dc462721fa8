"""Layer: service (Sparkplug). Data kept on disk while the broker is away, bounded.

Records (topic and payload bytes) are appended to segment files in a directory of the state
directory; the oldest segment is deleted whole when the total would exceed ``max_bytes`` (its
records counted as dropped). After the reconnect the edge node reads the sealed segments oldest
first, publishes their records (marked historical) and deletes each segment once it went out;
what could not go out yet (another disconnect, a robot not born yet) is written back. Segments
left by a previous run are replayed too. Writes go through the page cache (no fsync per record): a
power cut may lose the newest records, never corrupts older ones (a torn last record is cut).

Each segment starts with its format's version (``SPOOL_FORMAT``): an 8-byte mark and a 16-bit
version, then (version 3) the metric catalogue its records were written with, then the records.
Version 1, written before segments carried one, is the records alone (no record starts with the
mark: its topic would be 18,499 bytes long); version 2 is the mark and version, then the records.
Both are read as they are, their catalogue unknown (``Segment.catalogue`` ``None``); a segment
of a newer version is refused by name, left on disk as it is and never replayed.

The catalogue (``SpoolCatalogue``: per robot, each metric's alias, name and datatype) is what a
DDATA's aliases mean: the edge node declares per-robot metrics that depend on the configuration
(every alarm of the robot's alarm engine), so a segment written under another configuration
names other metrics by the same aliases. Version 3 keeps it with the segment: its SHA-256
fingerprint (32 bytes), its length (32 bits) and its canonical JSON, zlib-compressed, so that
the replay can tell a segment written with today's catalogue (``Segment.current``) from one to
translate by name. A segment whose catalogue cannot be read is set aside (``set_aside``: moved to
``aside/``, never replayed).

Imports only ``stored_format`` of the project.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import struct
import zlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from cobot_hmi.stored_format import FormatVersionError, StoredFormat

log = logging.getLogger(__name__)

SPOOL_FORMAT: Final = StoredFormat("Sparkplug spool segment", 3)
_MARK: Final = b"CHMISPL\n"
_FILE_HEADER: Final = struct.Struct("<8sH")
"""The mark and the format's version at the start of a segment."""
_CATALOGUE_HEADER: Final = struct.Struct("<32sI")
"""Version 3: the catalogue's fingerprint and its compressed length, after the version."""
SET_ASIDE: Final = "aside"
"""The directory (in the buffer's) of segments never to replay, kept for a person to look at."""

_HEADER: Final = struct.Struct("<HI")
"""Topic length, payload length."""
_MIN_SEGMENT_BYTES: Final = 64 * 1024
_SEGMENTS: Final = 16
"""About this many segments make up the bound: dropping one loses 1/16 of the buffer."""

Record = tuple[str, bytes]
CatalogueEntry = tuple[int, str, int]
"""A metric as a robot's births declare it: ``(alias, name, Sparkplug datatype)``."""
SpoolCatalogue = Mapping[str, Sequence[CatalogueEntry]]
"""Robot (device) name → its metrics: what the aliases of its buffered DDATA mean."""


def _canonical(catalogue: SpoolCatalogue) -> bytes:
    plain = {name: [list(entry) for entry in entries] for name, entries in catalogue.items()}
    return json.dumps(plain, sort_keys=True, separators=(",", ":")).encode()


def fingerprint(catalogue: SpoolCatalogue) -> bytes:
    """The catalogue's SHA-256 (of its canonical JSON): equal catalogues, equal fingerprints."""
    return hashlib.sha256(_canonical(catalogue)).digest()


def _file_header(catalogue: SpoolCatalogue) -> bytes:
    packed = zlib.compress(_canonical(catalogue))
    return (
        _FILE_HEADER.pack(_MARK, SPOOL_FORMAT.version)
        + _CATALOGUE_HEADER.pack(fingerprint(catalogue), len(packed))
        + packed
    )


@dataclass(frozen=True, slots=True)
class _Header:
    start: int
    """Where the records start."""
    version: int
    fingerprint: bytes | None = None
    """Version 3: the catalogue's fingerprint (``None`` before, or when torn)."""
    catalogue: bytes | None = None
    """Version 3: the compressed catalogue (``None`` before, or when torn)."""


def _read_header(data: bytes, where: Path) -> _Header:
    """Where a segment's records start (after its header; 0 in a version 1 segment) and what
    the header says, its version checked (``FormatVersionError`` for a newer one)."""
    if not data.startswith(_MARK):
        return _Header(0, 1)
    if len(data) < _FILE_HEADER.size:
        return _Header(len(data), 2)  # a header torn by a crash: no records
    _, found = _FILE_HEADER.unpack_from(data)
    version = SPOOL_FORMAT.read_version(found, where)
    if version < 3:
        return _Header(_FILE_HEADER.size, version)
    start = _FILE_HEADER.size + _CATALOGUE_HEADER.size
    if len(data) < start:
        return _Header(len(data), version)  # torn: no records, no catalogue
    digest, length = _CATALOGUE_HEADER.unpack_from(data, _FILE_HEADER.size)
    if len(data) < start + length:
        return _Header(len(data), version)
    return _Header(start + length, version, digest, data[start : start + length])


def _catalogue(header: _Header) -> SpoolCatalogue | None:
    """The catalogue a version 3 header carries, checked against its fingerprint (``None``
    when it cannot be read)."""
    if header.catalogue is None:
        return None
    try:
        text = zlib.decompress(header.catalogue)
        plain = json.loads(text)
    except (zlib.error, ValueError):
        return None
    if hashlib.sha256(text).digest() != header.fingerprint or not isinstance(plain, dict):
        return None
    try:
        return {
            str(name): [(int(alias), str(metric), int(kind)) for alias, metric, kind in entries]
            for name, entries in plain.items()
        }
    except (TypeError, ValueError):
        return None


@dataclass(frozen=True, slots=True)
class Segment:
    """A sealed segment as the replay reads it."""

    records: list[Record]
    version: int
    current: bool
    """Written with the buffer's catalogue (today's): its aliases mean what they mean now."""
    catalogue: SpoolCatalogue | None
    """The catalogue it was written with; ``None``: not known (versions 1 and 2)."""
    unreadable: bool = False
    """A version 3 segment whose catalogue cannot be read: never to replay (``set_aside``)."""


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
    """Segments ``NNNNNNNNNN.seg`` in ``directory``; at most ``max_bytes`` on disk; new ones
    written with ``catalogue`` (the metrics the writer declares today)."""

    def __init__(
        self, directory: Path, max_bytes: int, catalogue: SpoolCatalogue | None = None
    ) -> None:
        self.directory = directory
        self.max_bytes = max_bytes
        self.catalogue: SpoolCatalogue = catalogue or {}
        self.fingerprint = fingerprint(self.catalogue)
        self._header = _file_header(self.catalogue)
        self.records_set_aside = 0
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
                    start = _read_header(data, path).start
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
            # New records go to a new segment, under today's catalogue, not after the last
            # run's (written with its catalogue, perhaps another).
            self._new_segment()

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
            record = self._header + record  # a new segment starts with its version, catalogue
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
        return self.read_segment(path).records

    def read_segment(self, path: Path) -> Segment:
        """A segment's records and the catalogue they were written with."""
        try:
            data = path.read_bytes()
        except OSError:
            return Segment([], SPOOL_FORMAT.version, True, self.catalogue)
        header = _read_header(data, path)
        records = list(_records(data, header.start))
        if header.version < 3:
            return Segment(records, header.version, False, None)
        if header.fingerprint == self.fingerprint:
            return Segment(records, header.version, True, self.catalogue)
        catalogue = _catalogue(header)
        return Segment(records, header.version, False, catalogue, unreadable=catalogue is None)

    def set_aside(self, path: Path) -> Path:
        """A segment never to replay: moved to ``aside/`` (no longer counted), kept for a
        person to look at; where it went."""
        target = self.directory / SET_ASIDE / path.name
        for i, (candidate, size, count) in enumerate(self._segments):
            if candidate == path:
                del self._segments[i]
                self.records_buffered -= count
                self.bytes_buffered -= size
                self.records_set_aside += count
                break
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            path.replace(target)
        except OSError as error:
            log.warning("Sparkplug buffer: cannot set %s aside: %s", path, error)
        return target

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
        """Replay stopped part-way: keep what did not go out, still the oldest (``remaining``
        in today's aliases: it is written with today's catalogue)."""
        data = self._header + b"".join(encode_record(t, payload) for t, payload in remaining)
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
