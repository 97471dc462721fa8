"""Layer: health (pure). Imports the codec's ``Frame`` and the layout's T→O field table.

A run of one robot's frames as arrays, the engine's only input besides cycle boundaries: the
engine works on blocks (a cycle's frames, a second's) with numpy, never frame by frame, so its
cost per frame stays a few microseconds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import chain
from operator import attrgetter

import numpy as np
import numpy.typing as npt

from cobot_hmi.codec import Frame
from cobot_hmi.layout import T2O_ASSEMBLY, T2O_FIELDS

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


_JOINT_FIELDS = (
    "position_deg",
    "velocity_deg_s",
    "torque_nm",
    "current_a",
    "external_torque_nm",
    "temperature_c",
)


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

    def checked(self, after_s: float) -> tuple[FrameBlock, int]:
        """The frames fit to use: finite, and later than ``after_s`` and every frame before
        them (a frame out of order or with a NaN is dropped, not guessed at); and how many
        were dropped. ``ValueError`` naming the field for arrays of the wrong shape."""
        n = len(self)
        if self.time_s.ndim != 1:
            raise ValueError(f"time_s: expected a vector, got shape {self.time_s.shape}")
        joints: int | None = None
        for name in _JOINT_FIELDS:
            shape = getattr(self, name).shape
            if len(shape) != 2 or shape[0] != n or (joints is not None and shape[1] != joints):
                raise ValueError(f"{name}: expected shape ({n}, joints), got {shape}")
            joints = shape[1]
        for name in ("robot_state", "servo_on"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"{name}: expected shape ({n},), got {getattr(self, name).shape}")
        times_s = self.time_s
        if n and times_s[0] > after_s and np.all(times_s[1:] > times_s[:-1]):
            # The usual block: in order; every value finite if their sum is (a NaN or an
            # infinity makes it not; an overflow only sends a good block the long way).
            total = sum(float(getattr(self, name).sum()) for name in _JOINT_FIELDS)
            if math.isfinite(total + float(times_s.sum())):
                return self, 0
        finite = np.isfinite(self.time_s)
        for name in _JOINT_FIELDS:
            finite &= np.isfinite(getattr(self, name)).all(axis=1)
        times = np.where(finite, self.time_s, -np.inf)
        latest_before = np.maximum.accumulate(np.concatenate([[after_s], times]))[:-1]
        keep = finite & (self.time_s > latest_before)
        dropped = int(n - keep.sum())
        return (self if dropped == 0 else self.take(keep)), dropped

    def between(self, start_s: float, end_s: float) -> FrameBlock:
        """The frames with ``start_s <= time < end_s``."""
        keep = (self.time_s >= start_s) & (self.time_s < end_s)
        return self.take(keep)

    def take(self, keep: BoolArray | IntArray) -> FrameBlock:
        if keep.dtype == np.bool_ and keep.size == len(self) and keep.all():
            return self  # every frame kept: no copy (the arrays are never written to)
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
        if len(blocks) == 1:
            return blocks[0]
        return FrameBlock(
            *(
                np.concatenate([getattr(block, name) for block in blocks])
                for name in FrameBlock.__slots__
            )
        )

    @staticmethod
    def from_frames(times_s: Sequence[float], frames: Sequence[Frame]) -> FrameBlock:
        """The arrays of decoded frames (``times_s``: each frame's receive time)."""
        n = len(frames)
        joints = len(frames[0].joint_position) if n else 0
        # One pass over the frames for the six joint fields (their tuples chained into one
        # iterator of floats): a third of what six lists of tuples cost numpy to convert.
        values = np.fromiter(
            chain.from_iterable(chain.from_iterable(map(_JOINT_VALUES, frames))),
            dtype=np.float64,
            count=n * len(_FRAME_JOINT_FIELDS) * joints,
        ).reshape(n, len(_FRAME_JOINT_FIELDS), joints)
        return FrameBlock(
            np.asarray(times_s, dtype=np.float64),
            values[:, 0],
            values[:, 1],
            values[:, 2],
            values[:, 3],
            values[:, 4],
            values[:, 5],
            np.fromiter(map(_ROBOT_STATE, frames), dtype=np.int64, count=n),
            np.fromiter(map(_SERVO_ON, frames), dtype=np.bool_, count=n),
        )

    @staticmethod
    def from_payloads(
        times_s: Sequence[float] | FloatArray, payloads: Sequence[bytes]
    ) -> FrameBlock:
        """The arrays of undecoded T→O payloads (the frame records' ``raw``), read in place
        with numpy: the same values as ``from_frames`` of their decoded frames (a REAL is a
        float32, exact as a float64) at a sixth of its cost. ``ValueError`` for a payload not
        the assembly's size."""
        size = T2O_ASSEMBLY.size_bytes
        if any(len(p) != size for p in payloads):
            raise ValueError(f"expected T→O payloads of {size} bytes")
        records = np.frombuffer(b"".join(payloads), dtype=_PAYLOAD)
        joints = records["joints"].astype(np.float64)
        position, velocity, torque, current, external, temperature = (
            joints[:, k] for k in _PAYLOAD_ORDER
        )
        return FrameBlock(
            np.asarray(times_s, dtype=np.float64),
            position,
            velocity,
            torque,
            current,
            external,
            temperature,
            records["robot_state"].astype(np.int64),
            (records["flags"] & _SERVO_BIT) != 0,
        )


_FRAME_JOINT_FIELDS = (
    "joint_position",
    "joint_velocity",
    "joint_torque",
    "joint_motor_current",
    "joint_external_torque",
    "joint_motor_temperature",
)
"""The frame's fields for ``_JOINT_FIELDS``, in their order."""
_JOINT_VALUES = attrgetter(*_FRAME_JOINT_FIELDS)
_ROBOT_STATE = attrgetter("robot_state")
_SERVO_ON = attrgetter("servo_on")


def _payload_dtype() -> np.dtype[np.void]:
    """The T→O assembly's bytes as a numpy record: the robot state, its flags' byte holding
    servo on, and the six joint fields (six little-endian REALs each, contiguous)."""
    by_name = {f.name: f for f in T2O_FIELDS}
    reals = [by_name[name] for name in _FRAME_JOINT_FIELDS]
    first = min(f.offset for f in reals)
    layout_order = sorted(reals, key=lambda f: f.offset)
    if [f.offset for f in layout_order] != [first + 24 * k for k in range(len(reals))]:
        raise RuntimeError("the joint fields are no longer six contiguous REAL[6] (layout.py)")
    servo = by_name["servo_on"]
    assert servo.first_bit is not None
    return np.dtype(
        {
            "names": ["robot_state", "flags", "joints"],
            "formats": ["u1", "u1", ("<f4", (len(reals), 6))],
            "offsets": [by_name["robot_state"].offset, servo.offset + servo.first_bit // 8, first],
            "itemsize": T2O_ASSEMBLY.size_bytes,
        }
    )


_PAYLOAD = _payload_dtype()
_SERVO_BIT = 1 << (next(f for f in T2O_FIELDS if f.name == "servo_on").first_bit or 0) % 8
_OFFSETS = {f.name: f.offset for f in T2O_FIELDS}
_PAYLOAD_ORDER = [
    sorted(_FRAME_JOINT_FIELDS, key=_OFFSETS.__getitem__).index(name)
    for name in _FRAME_JOINT_FIELDS
]
"""Where each of ``FrameBlock``'s joint fields sits among the layout's six, in order."""
