"""Layer: health (pure). Imports the codec's ``Frame`` only.

A run of one robot's frames as arrays, the engine's only input besides cycle boundaries: the
engine works on blocks (a cycle's frames, a second's) with numpy, never frame by frame, so its
cost per frame stays a few microseconds.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from cobot_hmi.codec import Frame

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class FrameBlock:
    """``n`` frames in time order: times (s, any epoch, the same for the whole run) and per
    joint ``(n, 6)`` arrays, J1 first."""

    time_s: FloatArray
    position_deg: FloatArray
    velocity_deg_s: FloatArray
    torque_nm: FloatArray
    current_a: FloatArray
    external_torque_nm: FloatArray
    temperature_c: FloatArray
    robot_state: IntArray
    servo_on: BoolArray

    def __len__(self) -> int:
        return int(self.time_s.shape[0])

    def between(self, start_s: float, end_s: float) -> FrameBlock:
        """The frames with ``start_s <= time < end_s``."""
        keep = (self.time_s >= start_s) & (self.time_s < end_s)
        return self.take(keep)

    def take(self, keep: BoolArray | IntArray) -> FrameBlock:
        return FrameBlock(
            self.time_s[keep],
            self.position_deg[keep],
            self.velocity_deg_s[keep],
            self.torque_nm[keep],
            self.current_a[keep],
            self.external_torque_nm[keep],
            self.temperature_c[keep],
            self.robot_state[keep],
            self.servo_on[keep],
        )

    @staticmethod
    def concatenate(blocks: Sequence[FrameBlock]) -> FrameBlock:
        return FrameBlock(
            *(
                np.concatenate([getattr(block, name) for block in blocks])
                for name in FrameBlock.__slots__
            )
        )

    @staticmethod
    def from_frames(times_s: Sequence[float], frames: Sequence[Frame]) -> FrameBlock:
        """The arrays of decoded frames (``times_s``: each frame's receive time)."""

        def joints(name: str) -> FloatArray:
            return np.array([getattr(frame, name) for frame in frames], dtype=np.float64)

        return FrameBlock(
            np.asarray(times_s, dtype=np.float64),
            joints("joint_position"),
            joints("joint_velocity"),
            joints("joint_torque"),
            joints("joint_motor_current"),
            joints("joint_external_torque"),
            joints("joint_motor_temperature"),
            np.array([frame.robot_state for frame in frames], dtype=np.int64),
            np.array([frame.servo_on for frame in frames], dtype=np.bool_),
        )
