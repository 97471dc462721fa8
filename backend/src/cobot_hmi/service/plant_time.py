"""Layer: service. The plant's time zone: the one zone every time a person reads is written in
(the CSV exports and reports here; the pages take its name from the stream's hello and write
their times in it, ``frontend/src/lib/common/dates.ts``), so the panel, the kiosk, the exports and
the prints agree whatever zone the browser or the server's own clock is set to.

The ``time_zone`` setting names it (an IANA name, "Europe/Berlin"); empty: the service host's
own zone (``TZ``, else ``/etc/localtime``), UTC when that names none. One zone per process:
the service sets it when it is built (``use``), as a plant has one. Imports nothing of the
project.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Final
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

UTC_NAME: Final = "UTC"


def check_zone_name(name: str) -> str:
    """``name`` if it is empty (the host's zone) or an IANA zone this machine knows;
    ``ValueError`` naming an example otherwise (the setting's check)."""
    if name and _zone(name) is None:
        raise ValueError(f"{name!r} is not an IANA time zone name (e.g. Europe/Berlin, UTC)")
    return name


def _zone(name: str) -> ZoneInfo | None:
    try:
        return ZoneInfo(name)
    except (ZoneInfoNotFoundError, ValueError):
        return None


def host_zone_name() -> str:
    """The IANA name of the host's own zone: ``TZ`` (``:Europe/Berlin`` too), else where
    ``/etc/localtime`` links into the zone database, else UTC."""
    given = os.environ.get("TZ", "").removeprefix(":")
    if given and _zone(given) is not None:
        return given
    try:
        target = str(Path("/etc/localtime").resolve())
    except OSError:
        return UTC_NAME
    _, found, name = target.partition("zoneinfo/")
    return name if found and _zone(name) is not None else UTC_NAME


class _PlantZone:
    """The process's plant zone (``use``), the host's until the service says otherwise."""

    def __init__(self) -> None:
        self.name = host_zone_name()
        self.zone = ZoneInfo(self.name)

    def use(self, name: str) -> None:
        self.name = name or host_zone_name()
        self.zone = ZoneInfo(self.name)


PLANT_ZONE: Final = _PlantZone()
"""Read ``PLANT_ZONE.zone`` (a ``tzinfo``) and ``PLANT_ZONE.name`` (what the pages are told)."""
