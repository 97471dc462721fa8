"""Layer: service (pure). The kiosk's settings, declared once (``setting_fields``): how long its
plots look back and when the plant's shifts start (its cycle tile counts the cycles of the
shift in progress). The page is told them in its stream's hello (``kiosk``), as it learns the
robot's name and the plant's time zone, so every kiosk of a site shows the same without a word
in its URL (docs/operations.md, "Kiosk")."""

from __future__ import annotations

import re
from typing import Annotated, Final

from pydantic import AfterValidator, BaseModel, ConfigDict

from cobot_hmi.service.setting_fields import CommaList, setting

SHIFT_START_PATTERN: Final = re.compile(r"^([01]\d|2[0-3]):([0-5]\d)$")


def _check_shift_starts(starts: list[str]) -> list[str]:
    """Each a time of day HH:MM (24 h), at least one, none twice; sorted."""
    if not starts:
        raise ValueError("at least one shift start, HH:MM (e.g. 06:00,14:00,22:00)")
    bad = [s for s in starts if SHIFT_START_PATTERN.match(s) is None]
    if bad:
        raise ValueError(f"{', '.join(bad)}: a shift starts at a time of day HH:MM, e.g. 06:00")
    if len(set(starts)) != len(starts):
        raise ValueError("a shift start is given twice")
    return sorted(starts)


ShiftStarts = Annotated[CommaList, AfterValidator(_check_shift_starts)]


class KioskSettings(BaseModel):
    """The kiosk's plots' window and the plant's shifts."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kiosk_plot_window_s: float = setting(
        30.0,
        "how far the kiosk's plots look back, s (at least one cycle of the robot)",
        ge=5.0,
        le=600.0,
        allow_inf_nan=False,
    )
    shift_starts: ShiftStarts = setting(
        ["06:00", "14:00", "22:00"],
        "when the plant's shifts start, HH:MM in the plant's time zone (time_zone), comma "
        "separated: the kiosk counts the cycles of the shift in progress",
    )

    def kiosk_hello(self) -> dict[str, object]:
        """What a page's stream hello tells it (``kiosk``)."""
        return {"plot_window_s": self.kiosk_plot_window_s, "shift_starts": list(self.shift_starts)}
