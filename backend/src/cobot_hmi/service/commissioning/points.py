"""Layer: service. The points an I/O checkout goes through: every I/O channel and bit register of
the layout (``cobot_hmi.layout`` via the taggable points of ``service.storage.tags``), each an
input the service watches in the robot's frames or an output the checker switches. Pure.

Inputs (the robot reports them, T→O only): DI 1–16, Tool DI 1–6, AI 0–1 and the bit output
registers (the robot program sets them). Outputs (the PLC commands them, O→T): DO 1–16,
Tool DO 1–6, AO 0–1 and the bit input registers. The layout labels both register banks
"Register n"; a checkout names them by direction as the robot sees them, "Register in 12"
(written by us) and "Register out 12" (written by the robot program).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final, Literal

from cobot_hmi.layout import CipType, Direction, field_by_name
from cobot_hmi.service.storage.tags import POINTS

PointKind = Literal["input", "output"]
Signal = Literal["digital", "analog"]

_REGISTER_LABELS: Final = {
    "bit_input_registers": "Register in",
    "bit_output_registers": "Register out",
}


@dataclass(frozen=True, slots=True)
class CheckPoint:
    key: str
    """``field.index`` as the API keys elements (``controlbox_di.4`` is DI 5)."""
    label: str
    field: str
    index: int
    kind: PointKind
    signal: Signal


def _label(field: str, label: str) -> str:
    prefix = _REGISTER_LABELS.get(field)
    return label.replace("Register", prefix, 1) if prefix else label


def _points() -> tuple[CheckPoint, ...]:
    out = []
    for p in POINTS:
        kind: PointKind = "output" if Direction.O_TO_T.value in p.directions else "input"
        direction = Direction.O_TO_T if kind == "output" else Direction.T_TO_O
        real = field_by_name(direction, p.field).cip_type is CipType.REAL
        out.append(
            CheckPoint(
                p.key,
                _label(p.field, p.label),
                p.field,
                p.index,
                kind,
                "analog" if real else "digital",
            )
        )
    return tuple(out)


CHECK_POINTS: Final = _points()
"""Every point of a checkout, in layout order."""
CHECK_POINTS_BY_KEY: Final = {p.key: p for p in CHECK_POINTS}
DIGITAL_INPUT_FIELDS: Final = tuple(
    dict.fromkeys(p.field for p in CHECK_POINTS if p.kind == "input" and p.signal == "digital")
)
"""The T→O bit fields whose edges mark a point seen."""
ANALOG_SAMPLES: Final = 2
"""Values an analog input records (at two points the checker chooses) before it is seen."""
