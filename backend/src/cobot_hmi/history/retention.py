"""Layer: history storage. Imports only the history segments.

Retention of closed segments, every robot's together: delete the oldest segment first while the
oldest is older than ``max_age_s`` (its last frame) or the recordings take more than
``max_bytes`` on disk, whichever comes first. The open segments (journals) are never deleted;
they count towards the size.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from pathlib import Path

from cobot_hmi.history.segments import Segment, list_journals, list_robots, list_segments


@dataclass(slots=True)
class RetentionResult:
    deleted: list[Segment] = field(default_factory=list)
    bytes_freed: int = 0
    bytes_kept: int = 0
    """Bytes on disk after the pass (closed segments and journals)."""


def enforce(root: Path, *, now_s: float, max_age_s: float, max_bytes: int) -> RetentionResult:
    """One retention pass over every robot's recording under ``root``."""
    segments: list[tuple[Segment, int]] = []
    total = 0
    for robot in list_robots(root):
        for segment in list_segments(root, robot):
            size = segment.size_bytes()
            segments.append((segment, size))
            total += size
        for _, path in list_journals(root, robot):
            with contextlib.suppress(OSError):
                total += path.stat().st_size
    segments.sort(key=lambda pair: (pair[0].end_us, pair[0].start_us))
    result = RetentionResult()
    oldest_kept_us = (now_s - max_age_s) * 1e6
    for segment, size in segments:
        too_old = segment.end_us < oldest_kept_us
        if not too_old and total <= max_bytes:
            break
        # The rollup goes last: a segment's ``.parquet`` never stays without its cells.
        for path in (segment.path, segment.rollup_path):
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
        total -= size
        result.deleted.append(segment)
        result.bytes_freed += size
    result.bytes_kept = total
    return result
