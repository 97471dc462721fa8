"""Layer: service (pure). The cycle trigger as a setting, declared once.

``CycleSettings`` is a pydantic model of one field, ``cycle_trigger``. Both a robot's settings
(a ``[[robots]]`` table's ``cycle_trigger``) and the cell's (``robots.cell_settings``) inherit
it: at the top level it is every robot's default and the one-robot shortcut's trigger (TOML key
``cycle_trigger``, ``COBOT_HMI_CYCLE_TRIGGER``, ``--cycle-trigger``). The text is checked
against the layout when the settings load (``cycle_trigger.parse_trigger``).
"""

from __future__ import annotations

from pydantic import BaseModel, Field, field_validator

from cobot_hmi.service.robots.cycle_trigger import CycleTrigger, parse_trigger


class CycleSettings(BaseModel):
    """What starts a robot's cycle (docs/operations.md, "Cycle timing")."""

    cycle_trigger: str = Field(
        default="",
        description=(
            "what starts a cycle: FIELD.INDEX:rising|falling (a bit of the frame: "
            "bit_output_registers.63, controlbox_di.4 is DI 5), FLAG:rising|falling or "
            "state:NAME; empty: no cycle timing"
        ),
    )

    @field_validator("cycle_trigger")
    @classmethod
    def _valid_trigger(cls, text: str) -> str:
        parse_trigger(text)  # TriggerError is a ValueError: pydantic reports it
        return text.strip()

    @property
    def cycle_trigger_parsed(self) -> CycleTrigger | None:
        return parse_trigger(self.cycle_trigger)
