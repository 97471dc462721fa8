"""Layer: service. The WHERE clause of a searchable table: columns equal to values, a time range
(``since`` inclusive, ``until`` exclusive) and a text (``q``) that any of the table's word
columns contains, case-insensitively (``LIKE`` with ``%`` and ``_`` taken literally; SQLite's
``LIKE`` folds ASCII case). Used by the event log, the audit trail and the alarm history.
A text finds its synonyms too (``synonyms``): people write "e-stop" or "estop" where the
records say "Emergency stop". Imports nothing of the project.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Final

_SYNONYMS: Final = ((re.compile(r"\be[-\s]?stop", re.IGNORECASE), "emergency stop"),)
"""What people write → the records' words ("e-stop", "E stop", "estop" → "emergency stop")."""


def synonyms(text: str) -> list[str]:
    """``text`` and, where it uses a short form, the same text in the records' words:
    ``"e-stop reset"`` → ``["e-stop reset", "emergency stop reset"]``."""
    out = [text]
    for short, words in _SYNONYMS:
        expanded = short.sub(words, text)
        if expanded not in out:
            out.append(expanded)
    return out


def like_pattern(text: str) -> str:
    """``text`` as a ``LIKE … ESCAPE '\\'`` pattern matching it anywhere."""
    escaped = text.replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_")
    return f"%{escaped}%"


@dataclass(frozen=True, slots=True)
class Search:
    """A time range (``since`` inclusive, ``until`` exclusive, s since the epoch) and a text."""

    since: float | None = None
    until: float | None = None
    q: str | None = None

    def where(
        self,
        equal: Mapping[str, object | None],
        text_columns: Sequence[str],
        *,
        time_column: str = "time",
    ) -> tuple[str, list[object]]:
        """``("WHERE …", params)`` for ``equal`` (columns equal to values; ``None``: no
        condition) and this search; ``("", [])`` when nothing is asked."""
        clauses: list[str] = []
        params: list[object] = []
        for column, value in equal.items():
            if value is not None:
                clauses.append(f"{column} = ?")
                params.append(value)
        if self.since is not None:
            clauses.append(f"{time_column} >= ?")
            params.append(self.since)
        if self.until is not None:
            clauses.append(f"{time_column} < ?")
            params.append(self.until)
        if self.q and text_columns:
            patterns = [like_pattern(text) for text in synonyms(self.q)]
            likes = " OR ".join(f"{c} LIKE ? ESCAPE '\\'" for _ in patterns for c in text_columns)
            clauses.append(f"({likes})")
            params.extend(pattern for pattern in patterns for _ in text_columns)
        return ("WHERE " + " AND ".join(clauses)) if clauses else "", params


NO_SEARCH: Final = Search()
