"""Layer: pure (imports nothing of the project). The version every stored format carries.

Everything the product keeps on disk between runs says which version of its format it is:
the history's journals, segments and cells files (``history/formats.py``), the users file
(``service/access/users.py``) and the Sparkplug spool (``sparkplug/buffer.py``). The database
carries its own in ``PRAGMA user_version`` (``service/storage/migrations.py``).

A file written before formats carried a version is version 1 of its format, read by the same
code that read it then (its reader upgrades it as it reads); a file of a version newer than
this build knows is refused by name (``FormatVersionError``), never guessed at: an older
``cobot-hmi`` started on a newer one's state directory must not misread or rewrite it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

UNVERSIONED: Final = 1
"""The version of a file written before its format carried one."""


class FormatVersionError(ValueError):
    """A stored file whose format version this build cannot read (newer, or not a number)."""

    def __init__(self, where: str, what: str, found: str, newest: int) -> None:
        super().__init__(
            f"{where}: {what} version {found}; this cobot-hmi reads versions "
            f"{UNVERSIONED} to {newest} (a newer cobot-hmi wrote it: upgrade to read it)"
        )
        self.where = where
        self.what = what
        self.found = found
        self.newest = newest


@dataclass(frozen=True, slots=True)
class StoredFormat:
    """One stored format: what it is called in messages and the version written today."""

    what: str
    """In words, as an error names it (``"history journal"``)."""
    version: int
    """The version written today; every version from ``UNVERSIONED`` up is read."""

    def read_version(self, found: object, where: object) -> int:
        """The version a file says it is (``found``: its recorded text, number or bytes;
        ``None`` for a file written before versions were recorded), checked readable;
        ``where`` names the file in the error."""
        if found is None:
            return UNVERSIONED
        text = found.decode("ascii", "replace") if isinstance(found, bytes) else str(found)
        try:
            version = int(text)
        except ValueError:
            raise FormatVersionError(str(where), self.what, repr(text), self.version) from None
        if not UNVERSIONED <= version <= self.version:
            raise FormatVersionError(str(where), self.what, str(version), self.version)
        return version


__all__ = ["UNVERSIONED", "FormatVersionError", "StoredFormat"]
