"""Layer: emulator. Imports the layout's generated types and the codec.

A robot that stands still: a plausible fixed frame (STANDALONE_STANDBY, servo on, at the pose
of the published M1013 forward-kinematics check in docs/emulator.md) whose actual outputs follow
the last command, and whose bit output registers echo the bit input registers. Issue 3 allows a
static frame; the simulated robot (``emulator/robot/``) replaces it.
"""

from __future__ import annotations

import math

from cobot_hmi.codec import CommandImage, Frame, zero_command, zero_frame
from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.generated.frames import ControllerVersion, RobotState


def standing_frame() -> Frame:
    """The fixed part of the frame: a robot at rest, servo on, in standalone standby."""
    return zero_frame()._replace(
        controlbox_di=(True, False) + (False,) * 14,
        analog_input_type=(0, 1),
        analog_input=(4.0, 0.0),
        controller_version=ControllerVersion(2, 12, 0),
        robot_state=int(RobotState.STANDALONE_STANDBY),
        servo_on=True,
        joint_position=(30.0, 0.0, 90.0, 0.0, 90.0, 0.0),
        joint_motor_temperature=(31.5, 32.0, 31.0, 30.5, 30.0, 29.5),
        tcp_position=(466.9, 309.4, 651.5),
        tcp_orientation=(75.0, 180.0, 45.0),
    )


class StaticRobot:
    """A :class:`~cobot_hmi.emulator.process_image.ProcessImage` with a fixed frame."""

    def __init__(
        self, idle_behaviour: IdleBehaviour = IdleBehaviour.HOLD, base: Frame | None = None
    ) -> None:
        self.idle_behaviour = idle_behaviour
        self._base = base if base is not None else standing_frame()
        self._command = zero_command()
        self._frame = self._compose()
        self.commands_consumed = 0
        self.idle_calls = 0

    def _compose(self) -> Frame:
        command = self._command
        return self._base._replace(
            controlbox_do=command.controlbox_do,
            tool_do=command.tool_do,
            analog_output_type=command.analog_output_type,
            analog_output=command.analog_output,
            bit_output_registers=command.bit_input_registers,
        )

    @property
    def data_period_s(self) -> float:
        return math.inf  # it changes only when commanded

    def produce_frame(self, now_s: float) -> Frame:
        return self._frame

    def consume_command(self, image: CommandImage, now_s: float) -> None:
        self.commands_consumed += 1
        self._command = image
        self._frame = self._compose()

    def outputs_idle(self, now_s: float) -> None:
        self.idle_calls += 1
        if self.idle_behaviour is IdleBehaviour.CLEAR:
            self._command = zero_command()
            self._frame = self._compose()

    def command_image(self) -> CommandImage:
        return self._command
