"""Layer: service. The query parameters every searchable list shares: a text (``q``) and a
time range (``from``, ``to``), in the same words on every route (the events, the audit trail,
the alarm history, the cycles).

A time is seconds since the epoch or ISO 8601 with its offset (``2026-11-27T12:00:00+01:00``;
without an offset it is the plant's time zone, ``plant_time``). The text matches,
case-insensitively, any part of a row's words (``storage.search``).
"""

from __future__ import annotations

import math
from datetime import datetime
from typing import Annotated, Final

from fastapi import Query
from pydantic import AfterValidator

from cobot_hmi.service.plant_time import PLANT_ZONE

_TIME_HELP: Final = (
    "seconds since the epoch (1764244800.5), or ISO 8601 (2026-11-27T12:00:00+01:00; without "
    "an offset: the plant's time zone, the time_zone setting)"
)


def epoch_s(text: str | None) -> float | None:
    """A time parameter as seconds since the epoch; ``ValueError`` saying what it accepts."""
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        try:
            moment = datetime.fromisoformat(text)
        except ValueError:
            raise ValueError(f"expected {_TIME_HELP}; got {text!r}") from None
        if moment.tzinfo is None:  # the plant's time, as the pages show it
            moment = moment.replace(tzinfo=PLANT_ZONE.zone)
        return moment.timestamp()
    if not math.isfinite(value):
        raise ValueError(f"expected a finite time, got {text!r}")
    return value


def _check_time(text: str | None) -> str | None:
    epoch_s(text)  # refused here with its reason (422 naming the parameter)
    return text


From = Annotated[
    str | None,
    Query(alias="from", description=f"from this time on (inclusive): {_TIME_HELP}"),
    AfterValidator(_check_time),
]
To = Annotated[
    str | None,
    Query(alias="to", description=f"before this time (exclusive): {_TIME_HELP}"),
    AfterValidator(_check_time),
]
Text = Annotated[
    str | None,
    Query(
        min_length=1,
        max_length=200,
        description="only rows whose words contain this text (case-insensitive)",
    ),
]
