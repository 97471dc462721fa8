"""Layer: service. Tag names: a name an admin gives an I/O point or a bit register of one robot
("DO 3 — gripper close"), kept in the service's database and shown next to the spec's label
wherever the point appears (events, audit rows, alarms, the panel).

A point is keyed as the API keys elements, ``field.index`` with the frame array's 0-based index
(``controlbox_do.2`` is DO 3, ``service.labels``); a field that is both an actual output (T→O)
and a command (O→T), such as ``controlbox_do``, is one point with one name. The taggable points
are the layout's I/O and bit register channels (not the analog type codings).

``TagBook`` holds every robot's names in memory (lookups on the event path are dict reads) and
writes changes through the ``Store`` (``Store.call``, its worker thread) into the ``tags`` table
(created by ``service.storage.migrations``). CSV: ``key,label,name``
with a header; an import names each point by its key, its label, or both (then they must agree:
a sheet edited with "DO 3" next to ``controlbox_do.3`` is refused, not half-applied).
"""

from __future__ import annotations

import csv
import io
import sqlite3
import unicodedata
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

from cobot_hmi.layout import O2T_FIELDS, T2O_FIELDS

if TYPE_CHECKING:
    from cobot_hmi.service.storage.store import Store

MAX_TAG_CHARS: Final = 64
CSV_COLUMNS: Final = ("key", "label", "name")
_TAGGABLE_GROUPS: Final = frozenset({"I/O", "Bit Registers"})


@dataclass(frozen=True, slots=True)
class TagPoint:
    """One taggable point: its key, the spec's label, the field and index it is."""

    key: str
    label: str
    field: str
    index: int
    directions: tuple[str, ...]
    """``T2O`` (the robot reports it), ``O2T`` (the PLC commands it), or both."""


def _points() -> tuple[TagPoint, ...]:
    found: dict[str, TagPoint] = {}
    for f in (*T2O_FIELDS, *O2T_FIELDS):
        if f.group not in _TAGGABLE_GROUPS or not f.channels or f.value_names:
            continue
        for index, label in enumerate(f.channels):
            key = f"{f.name}.{index}"
            point = found.get(key)
            directions = (*point.directions, f.direction.value) if point else (f.direction.value,)
            found[key] = TagPoint(key, label, f.name, index, directions)
    return tuple(found.values())


POINTS: Final = _points()
"""Every taggable point, in layout order."""
POINTS_BY_KEY: Final = {p.key: p for p in POINTS}
_POINTS_BY_LABEL: Final = {p.label.casefold(): p for p in POINTS}


class TagError(ValueError):
    """A tag change that cannot be applied; ``field`` names the key or CSV line at fault."""

    def __init__(self, field: str | None, reason: str) -> None:
        super().__init__(reason)
        self.field = field
        self.reason = reason


def clean_name(key: str, name: object) -> str:
    """A tag name checked: text, at most ``MAX_TAG_CHARS``, no control characters, trimmed
    (empty: no name)."""
    if name is None:
        return ""
    if not isinstance(name, str):
        raise TagError(key, f"{key}: a tag name is text, got {type(name).__name__}")
    text = name.strip()
    if len(text) > MAX_TAG_CHARS:
        raise TagError(key, f"{key}: a tag name has at most {MAX_TAG_CHARS} characters")
    if any(unicodedata.category(c).startswith("C") for c in text):
        raise TagError(key, f"{key}: a tag name has no control characters")
    return text


def check_tags(tags: Mapping[str, object]) -> dict[str, str]:
    """A whole set of names checked against the taggable points (nothing applied on an error);
    empty names dropped."""
    out: dict[str, str] = {}
    for key, name in tags.items():
        point = POINTS_BY_KEY.get(key)
        if point is None:
            raise TagError(
                key,
                f"{key!r} is not a taggable point: field.index with a 0-based index, e.g. "
                "controlbox_do.2 (DO 3); see GET …/tags for the list",
            )
        text = clean_name(key, name)
        if text:
            out[key] = text
    return out


def to_csv(tags: Mapping[str, str]) -> str:
    """Every taggable point as CSV ``key,label,name`` (an untagged point's name empty)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for point in POINTS:
        writer.writerow((point.key, point.label, tags.get(point.key, "")))
    return out.getvalue()


def from_csv(text: str) -> dict[str, str]:
    """Names from CSV (``key,label,name``; ``key`` or ``label`` may be left out or empty, not
    both); a line whose key and label disagree is refused naming the line."""
    reader = csv.DictReader(io.StringIO(text.lstrip("\ufeff")))
    columns = [c.strip().lower() for c in (reader.fieldnames or [])]
    if "name" not in columns or not ({"key", "label"} & set(columns)):
        raise TagError(None, "the CSV needs a header with name and key or label (key,label,name)")
    reader.fieldnames = columns
    tags: dict[str, str] = {}
    for line_number, row in enumerate(reader, start=2):
        where = f"line {line_number}"
        key = (row.get("key") or "").strip()
        label = (row.get("label") or "").strip()
        name = row.get("name") or ""
        if not key and not label:
            if not name.strip():
                continue  # an empty line
            raise TagError(where, f"{where}: give the point's key or label")
        point = POINTS_BY_KEY.get(key) if key else _POINTS_BY_LABEL.get(label.casefold())
        if point is None:
            what = f"key {key!r}" if key else f"label {label!r}"
            raise TagError(where, f"{where}: {what} is not a taggable point")
        if key and label and point.label.casefold() != label.casefold():
            raise TagError(
                where,
                f"{where}: {key} is {point.label}, not {label} (indexes are 0-based: "
                f"{point.key} is {point.label})",
            )
        if point.key in tags:
            raise TagError(where, f"{where}: {point.label} ({point.key}) is named twice")
        text = clean_name(where, name)
        if text:
            tags[point.key] = text
    return tags


class TagBook:
    """One robot's tag names, in memory (``names``, replaced whole on a change, so a reader's
    view never changes under it) and in the database."""

    def __init__(self, robot: str) -> None:
        self.robot = robot
        self.names: Mapping[str, str] = {}
        """``{key: name}``; a new dict after each change."""

    def name(self, key: str) -> str | None:
        return self.names.get(key)

    async def load(self, store: Store) -> None:
        """Read the robot's names (at start, after ``store.open``)."""

        def read(db: sqlite3.Connection) -> list[tuple[str, str]]:
            rows: list[tuple[str, str]] = db.execute(
                "SELECT key, name FROM tags WHERE robot = ?", (self.robot,)
            ).fetchall()
            return rows

        self.names = {key: name for key, name in await store.call(read) if key in POINTS_BY_KEY}

    async def replace(self, store: Store, tags: Mapping[str, object]) -> dict[str, str]:
        """Replace the names with ``tags`` (checked whole first: ``TagError``); durable before
        it returns. The new names."""
        checked = check_tags(tags)
        robot = self.robot

        def write(db: sqlite3.Connection) -> None:
            db.execute("DELETE FROM tags WHERE robot = ?", (robot,))
            db.executemany(
                "INSERT INTO tags (robot, key, name) VALUES (?, ?, ?)",
                [(robot, key, name) for key, name in checked.items()],
            )

        await store.call(write)
        self.names = dict(checked)
        return dict(checked)
