"""Layer: service. The WHERE clause of a searchable table: columns equal to values, a time range
(``since`` inclusive, ``until`` exclusive) and a text (``q``) that any of the table's word
columns contains, case-insensitively (``LIKE`` with ``%`` and ``_`` taken literally; SQLite's
``LIKE`` folds ASCII case). Used by the event log, the audit trail and the alarm history.
Imports nothing of the project.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Final


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
            pattern = like_pattern(self.q)
            likes = " OR ".join(f"{c} LIKE ? ESCAPE '\\'" for c in text_columns)
            clauses.append(f"({likes})")
            params.extend(pattern for _ in text_columns)
        return ("WHERE " + " AND ".join(clauses)) if clauses else "", params


NO_SEARCH: Final = Search()
