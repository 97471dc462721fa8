"""Layer: health (pure). Imports nothing of the project.

A joint's verdict in three words, ok / watch / act, from its findings, and the reason in a
sentence a maintenance planner reads: the worst finding first, then the others
("J3: friction 14 % above its baseline of 1 Dec at the same speed and temperature, rising 2 % a
week").
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Final

LEVELS: Final = ("ok", "watch", "act")


@dataclass(frozen=True, slots=True)
class Finding:
    level: int
    """0 ok, 1 watch, 2 act (an index of ``LEVELS``)."""
    text: str


def level_of(value: float | None, watch: float, act: float) -> int:
    if value is None:
        return 0
    return 2 if value >= act else 1 if value >= watch else 0


def day_text(epoch_s: float) -> str:
    """``1 Dec`` (UTC) for the baseline's date."""
    parts = time.gmtime(epoch_s)
    return f"{parts.tm_mday} {time.strftime('%b', parts)}"


def friction_text(percent: float, baseline_s: float, per_week: float | None) -> str:
    word = "above" if percent >= 0 else "below"
    text = (
        f"friction {abs(percent):.0f} % {word} its baseline of {day_text(baseline_s)} "
        "at the same speed and temperature"
    )
    if per_week is not None and abs(per_week) >= 0.5:
        text += f", {'rising' if per_week > 0 else 'falling'} {abs(per_week):.1f} % a week"
    return text


def verdict(joint: int, findings: list[Finding], quiet: str) -> tuple[str, str]:
    """The joint's verdict and reason: the findings that matter, worst first, else ``quiet``."""
    worst = max((f.level for f in findings), default=0)
    shown = sorted((f for f in findings if f.level > 0), key=lambda f: -f.level)
    body = "; ".join(f.text for f in shown) if shown else quiet
    return LEVELS[worst], f"J{joint}: {body}"
