"""Layer: history storage. Imports only the layout's version and ``stored_format``.

The recording's stored formats and their versions, written into each file with the layout
version its frames were recorded with (``LAYOUT_VERSION`` of ``layout.py``): in the schema
metadata of an Arrow IPC journal or cells file, in the key-value metadata of a Parquet
segment's footer.

- history journal (``START.journal.arrows``, ``segments``): version 1 carries no version and is
  either the payload form (``journal_form``) or, written earlier still, the element columns;
  version 2 is the payload form with its versions. Both are read (``journal_form.expand``).
- history segment (``START-END.parquet``): version 1 carries no version; version 2 has its
  versions in the footer. The columns are the same.
- history cells file (``START-END.cells.arrow``, ``cells``): version 1 carries no version (with
  or without its coarser levels); version 2 has its versions.

A file of a newer version, or of frames in a newer layout, is refused by name
(``stored_format.FormatVersionError``): readers skip it, the closer leaves it on disk.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Final

from cobot_hmi.layout import LAYOUT_VERSION
from cobot_hmi.stored_format import StoredFormat

FORMAT_VERSION_KEY: Final = b"cobot_hmi.format_version"
LAYOUT_VERSION_KEY: Final = b"cobot_hmi.layout_version"

JOURNAL: Final = StoredFormat("history journal", 2)
SEGMENT: Final = StoredFormat("history segment", 2)
CELLS: Final = StoredFormat("history cells file", 2)
RECORDED_LAYOUT: Final = StoredFormat("recorded frames' layout", LAYOUT_VERSION)


def version_metadata(stored: StoredFormat) -> dict[bytes, bytes]:
    """What a file of ``stored`` carries today: its format's version and the layout's."""
    return {
        FORMAT_VERSION_KEY: str(stored.version).encode(),
        LAYOUT_VERSION_KEY: str(LAYOUT_VERSION).encode(),
    }


def check_versions(
    stored: StoredFormat, metadata: Mapping[bytes, bytes] | None, where: Path | str
) -> int:
    """The format version of a file whose metadata is ``metadata``; ``FormatVersionError``
    naming ``where`` when this build cannot read the format or the frames' layout."""
    found = metadata or {}
    version = stored.read_version(found.get(FORMAT_VERSION_KEY), where)
    RECORDED_LAYOUT.read_version(found.get(LAYOUT_VERSION_KEY), where)
    return version


__all__ = [
    "CELLS",
    "FORMAT_VERSION_KEY",
    "JOURNAL",
    "LAYOUT_VERSION_KEY",
    "RECORDED_LAYOUT",
    "SEGMENT",
    "check_versions",
    "version_metadata",
]
