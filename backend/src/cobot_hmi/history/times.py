"""Layer: history storage. Imports nothing of the project.

Times as the history API and ``cobot-hmi export`` take them: epoch seconds (``1732430000.5``)
or ISO 8601 (``2026-11-24T06:00:00Z``, ``2026-11-24T07:00:00+01:00``; without an offset: UTC),
and the ISO 8601 form they write.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime


class TimeFormatError(ValueError):
    pass


def parse_time(text: str) -> float:
    """Epoch seconds of ``text`` (module docstring); ``TimeFormatError`` otherwise."""
    text = text.strip()
    try:
        value = float(text)
    except ValueError:
        pass
    else:
        if not math.isfinite(value):
            raise TimeFormatError(f"{text!r} is not a finite time")
        return value
    try:
        moment = datetime.fromisoformat(text.replace("z", "Z"))
    except ValueError:
        raise TimeFormatError(
            f"{text!r} is neither epoch seconds nor an ISO 8601 time (e.g. 2026-11-24T06:00:00Z)"
        ) from None
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    return moment.timestamp()


def iso(time_s: float) -> str:
    """``2026-11-24T06:00:00.123456Z``"""
    return datetime.fromtimestamp(time_s, UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def compact_iso(time_s: float) -> str:
    """A file-name-safe form: ``20261124T060000Z``."""
    return datetime.fromtimestamp(time_s, UTC).strftime("%Y%m%dT%H%M%SZ")
