"""Layer: emulator. Imports only the codec's types.

The interface between the EtherNet/IP target and the robot behind it. The target calls it from
its event loop; an implementation must return quickly (it runs once per produced packet).
"""

from __future__ import annotations

from enum import StrEnum
from typing import Protocol

from cobot_hmi.codec import CommandImage, Frame


class IdleBehaviour(StrEnum):
    """What the robot's outputs do when their owner goes idle, times out or closes."""

    HOLD = "hold"
    """Keep the last commanded values."""
    CLEAR = "clear"
    """Switch every output off and set the analog outputs to zero."""


class ProcessImage(Protocol):
    @property
    def data_period_s(self) -> float:
        """How often the robot's data changes by itself at most (a controller refreshing its
        monitoring values on a period); 0 when every instant differs. The target then reads
        it once per wake-up rather than once per packet."""
        ...

    def produce_frame(self, now_s: float) -> Frame:
        """The T→O frame to send now (``now_s``: epoch seconds)."""
        ...

    def consume_command(self, image: CommandImage, now_s: float) -> None:
        """A new command image: from the owner in run, or an explicit Set_Attribute_Single."""
        ...

    def outputs_idle(self, now_s: float) -> None:
        """The owner went idle, timed out or closed: apply the idle behaviour."""
        ...

    def command_image(self) -> CommandImage:
        """The last commanded image (an explicit read of the O→T assembly)."""
        ...
