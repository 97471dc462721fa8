"""Layer: emulator. Imports only the codec's types.

The interface between the EtherNet/IP target and the robot behind it. The target calls it from
its event loop; an implementation must return quickly (it runs once per produced packet).
"""

from __future__ import annotations

from enum import StrEnum
from typing import Protocol, runtime_checkable

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


@runtime_checkable
class HoldsStill(Protocol):
    """A process image that can tell how long its frame stays as it is by itself (the
    simulated robot): the target then leaves the pump's periodic stream alone until then,
    rather than reading the robot again at every RPI only to find the same frame."""

    def frame_still_until_s(self) -> float:
        """Epoch seconds up to which ``produce_frame`` gives the frame it last gave, unless
        a command or a control action changes the robot meanwhile (the target reads it again
        after those anyway). A lower bound: the time of the last frame when unsure."""
        ...
