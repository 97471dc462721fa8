"""Layer: service. Output presets of one robot: named sets of outputs and registers ("Job 3:
registers 0–3 = 1100"), made by hand or from the current command image, exported and imported
as CSV or JSON, applied as ONE write through the write pipeline (all values or none).

A preset's items are ``{"field.index": value}`` over the O→T image (DO, Tool DO, AO type,
AO, bit input registers), checked against the layout by the write pipeline's own validation
(``writes.validation.plan_write``) when saved and again when applied. "All outputs off"
(every DO and Tool DO off) exists for every robot without being made and cannot be replaced
or deleted. Presets are kept in the ``presets`` table (``storage.migrations`` step 5).
"""

from __future__ import annotations

import csv
import io
import sqlite3
import time
import unicodedata
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

import orjson

from cobot_hmi.codec import CommandImage
from cobot_hmi.layout import O2T_FIELDS
from cobot_hmi.service.commissioning.points import CHECK_POINTS_BY_KEY
from cobot_hmi.service.errors import ApiError
from cobot_hmi.service.labels import element_label
from cobot_hmi.service.storage.store import Store
from cobot_hmi.service.writes.validation import WriteValidationError, plan_write

ALL_OUTPUTS_OFF: Final = "All outputs off"
MAX_NAME_CHARS: Final = 64
CSV_COLUMNS: Final = ("preset", "key", "label", "value")
_OFF_FIELDS: Final = ("controlbox_do", "tool_do")

PresetValue = bool | int | float


class PresetError(ApiError):
    """A preset that cannot be saved or read; ``field`` names the key or line at fault."""

    def __init__(self, status: int, reason: str, field: str | None = None) -> None:
        super().__init__(status, reason, field=field)


@dataclass(frozen=True, slots=True)
class Preset:
    name: str
    items: dict[str, PresetValue]
    created_at: float | None = None
    created_by: str | None = None
    builtin: bool = False

    def body(self) -> dict[str, dict[str, PresetValue]]:
        """The write pipeline's body: ``{"field": {"index": value}}``."""
        body: dict[str, dict[str, PresetValue]] = {}
        for key, value in self.items.items():
            name, _, index = key.partition(".")
            body.setdefault(name, {})[index] = value
        return body

    def answer(self) -> dict[str, object]:
        """``Preset`` of the API."""
        return {
            "name": self.name,
            "items": self.items,
            "labels": {k: label_of(k) for k in self.items},
            "created_at": self.created_at,
            "created_by": self.created_by,
            "builtin": self.builtin,
        }


def label_of(key: str) -> str:
    point = CHECK_POINTS_BY_KEY.get(key)
    return point.label if point is not None else (element_label(key) or key)


def all_outputs_off() -> Preset:
    items: dict[str, PresetValue] = {}
    for f in O2T_FIELDS:
        if f.name in _OFF_FIELDS:
            items.update({f"{f.name}.{i}": False for i in range(f.count)})
    return Preset(ALL_OUTPUTS_OFF, items, builtin=True)


def _image_items(image: CommandImage, fields: list[str] | None) -> dict[str, PresetValue]:
    items: dict[str, PresetValue] = {}
    for f in O2T_FIELDS:
        if fields is None or f.name in fields:
            values = getattr(image, f.name)
            items.update({f"{f.name}.{i}": values[i] for i in range(f.count)})
    return items


def clean_name(name: object) -> str:
    if not isinstance(name, str) or not name.strip():
        raise PresetError(422, "a preset needs a name", "name")
    text = name.strip()
    if len(text) > MAX_NAME_CHARS:
        raise PresetError(422, f"a preset's name has at most {MAX_NAME_CHARS} characters", "name")
    if any(unicodedata.category(c).startswith("C") for c in text) or "/" in text:
        raise PresetError(422, "a preset's name has no control characters and no '/'", "name")
    return text


def checked(name: object, items: Mapping[str, object], base: CommandImage) -> Preset:
    """A preset checked whole as the write pipeline will check its write."""
    text = clean_name(name)
    if text.casefold() == ALL_OUTPUTS_OFF.casefold():
        raise PresetError(409, f"{ALL_OUTPUTS_OFF!r} is built in: choose another name", "name")
    if not items:
        raise PresetError(422, "a preset holds at least one value", "items")
    preset = Preset(text, {})
    body: dict[str, dict[str, object]] = {}
    for key, value in items.items():
        name_part, dot, index = key.partition(".")
        if not dot:
            raise PresetError(422, f"{key!r}: an item is field.index, e.g. controlbox_do.2", key)
        body.setdefault(name_part, {})[index] = value
    try:
        plan = plan_write(body, base)
    except WriteValidationError as error:
        raise PresetError(422, error.reason, error.field) from None
    values = plan.values(plan.image)
    return Preset(preset.name, {k: _plain(v) for k, v in values.items()})


def _plain(value: object) -> PresetValue:
    if isinstance(value, bool | int | float):
        return value
    raise PresetError(422, f"{value!r} is not a value of an output")


def from_image(name: object, image: CommandImage, fields: list[str] | None) -> Preset:
    known = {f.name for f in O2T_FIELDS}
    for f in fields or []:
        if f not in known:
            raise PresetError(422, f"{f!r} is not an O→T field ({', '.join(known)})", "fields")
    return checked(name, _image_items(image, fields), image)


def changes(preset: Preset, image: CommandImage) -> list[dict[str, object]]:
    """What applying ``preset`` changes in the command image being sent, in its order."""
    out: list[dict[str, object]] = []
    for key, value in preset.items.items():
        name, _, index = key.partition(".")
        current = getattr(image, name)[int(index)]
        if current != value:
            out.append({"key": key, "label": label_of(key), "from": current, "to": value})
    return out


# --------------------------------------------------------------------------- CSV


def to_csv(presets: list[Preset]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for preset in presets:
        for key, value in preset.items.items():
            writer.writerow((preset.name, key, label_of(key), _csv_value(value)))
    return out.getvalue()


def _csv_value(value: PresetValue) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    return f"{value:g}" if isinstance(value, float) else str(value)


def from_csv(text: str) -> dict[str, dict[str, PresetValue]]:
    """``{preset: {key: value}}`` from the export's CSV (``preset,key,label,value``; the label
    is informative); bits as 0/1 or true/false, AO as numbers."""
    reader = csv.DictReader(io.StringIO(text))
    if reader.fieldnames is None or not {"preset", "key", "value"} <= set(reader.fieldnames):
        raise PresetError(422, "the CSV needs a header with preset,key,value", "csv")
    presets: dict[str, dict[str, PresetValue]] = {}
    for line, row in enumerate(reader, start=2):
        key = (row.get("key") or "").strip()
        name = (row.get("preset") or "").strip()
        raw = (row.get("value") or "").strip()
        if not key or not name:
            raise PresetError(422, f"line {line}: preset and key are needed", f"line {line}")
        presets.setdefault(name, {})[key] = _parse_value(key, raw, line)
    return presets


def _parse_value(key: str, raw: str, line: int) -> PresetValue:
    field = key.partition(".")[0]
    if field in ("analog_output",):
        try:
            return float(raw)
        except ValueError:
            raise PresetError(
                422, f"line {line}: {raw!r} is not a number", f"line {line}"
            ) from None
    if field == "analog_output_type":
        if raw in ("0", "1"):
            return int(raw)
        raise PresetError(422, f"line {line}: an AO type is 0 or 1", f"line {line}")
    words = {"1": True, "true": True, "on": True, "0": False, "false": False, "off": False}
    if raw.lower() in words:
        return words[raw.lower()]
    raise PresetError(422, f"line {line}: {raw!r} is not a bit (0/1)", f"line {line}")


# --------------------------------------------------------------------------- the table


class PresetBook:
    """One robot's presets in the database (the built-in one added on every read)."""

    def __init__(self, robot: str, store: Store) -> None:
        self.robot = robot
        self.store = store

    async def all(self) -> list[Preset]:
        rows = await self.store.call(
            lambda db: db.execute(
                "SELECT name, items, created_at, created_by FROM presets WHERE robot = ? "
                "ORDER BY name COLLATE NOCASE",
                (self.robot,),
            ).fetchall(),
            fsync=False,
        )
        saved = [Preset(n, orjson.loads(items), at, by) for n, items, at, by in rows]
        return [all_outputs_off(), *saved]

    async def get(self, name: str) -> Preset:
        for preset in await self.all():
            if preset.name == name:
                return preset
        raise PresetError(404, f"robot {self.robot} has no preset {name!r}", "preset")

    async def save(self, preset: Preset, by: str) -> Preset:
        saved = Preset(preset.name, preset.items, time.time(), by)

        def write(db: sqlite3.Connection) -> None:
            db.execute(
                "INSERT OR REPLACE INTO presets (robot, name, items, created_at, created_by) "
                "VALUES (?, ?, ?, ?, ?)",
                (self.robot, saved.name, orjson.dumps(saved.items).decode(), saved.created_at, by),
            )

        await self.store.call(write)
        return saved

    async def delete(self, name: str) -> None:
        if name == ALL_OUTPUTS_OFF:
            raise PresetError(409, f"{ALL_OUTPUTS_OFF!r} is built in: it cannot be deleted")
        deleted = await self.store.call(
            lambda db: (
                db.execute(
                    "DELETE FROM presets WHERE robot = ? AND name = ?", (self.robot, name)
                ).rowcount
            )
        )
        if not deleted:
            raise PresetError(404, f"robot {self.robot} has no preset {name!r}", "preset")
