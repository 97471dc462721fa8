"""Layer: health (pure). Imports ``health.frames`` and ``health.settings``.

Friction: what a joint needs at the same position and speed beyond its baseline, in the same
band of motor temperature. Gravity and inertia are even in the direction of motion at a given
position and acceleration, friction is odd: in each cell (joint, temperature band, position bin,
speed bin) the mean torque moving forward minus the mean torque moving back is twice the
friction there. A joint's figure is the cells it shares with its baseline, weighted by how many
frames each holds: ``Σ w·(F_now − F_base) / Σ w·F_base``.

Cells are sparse (a program visits a few hundred of the millions possible): a key per cell, a
slot per key, sums in numpy arrays indexed by slot.
"""

from __future__ import annotations

import numpy as np

from cobot_hmi.health.frames import FloatArray, FrameBlock, IntArray
from cobot_hmi.health.settings import HealthSettings

_BANDS = 100  # temperature bands from −40 °C
_POSITIONS = 100  # position bins from −500°
_SPEEDS = 100
_COLUMNS = 4  # torque sum forward, frames forward, torque sum back, frames back


class CellTable:
    """Per cell: forward and backward torque sums and frame counts (see the module docstring)."""

    def __init__(self, settings: HealthSettings) -> None:
        self._settings = settings
        self.slots: dict[int, int] = {}
        self.sums: FloatArray = np.zeros((64, _COLUMNS))

    def keys(self, block: FrameBlock) -> tuple[IntArray, IntArray, FloatArray]:
        """Each moving frame's cell key, direction column (0 forward, 2 back) and torque."""
        s = self._settings
        velocity = block.velocity_deg_s
        moving = (np.abs(velocity) >= s.min_speed_deg_s) & block.servo_on[:, None]
        joint = np.broadcast_to(np.arange(velocity.shape[1]), velocity.shape)
        band = np.clip(((block.temperature_c + 40.0) // s.temperature_band_c), 0, _BANDS - 1)
        position = np.clip((block.position_deg + 500.0) // s.position_bin_deg, 0, _POSITIONS - 1)
        speed = np.clip(np.abs(velocity) // s.speed_bin_deg_s, 0, _SPEEDS - 1)
        key = ((joint * _BANDS + band) * _POSITIONS + position) * _SPEEDS + speed
        column = np.where(velocity > 0.0, 0, 2)
        return (
            key[moving].astype(np.int64),
            column[moving].astype(np.int64),
            block.torque_nm[moving],
        )

    def add(self, block: FrameBlock) -> None:
        keys, columns, torques = self.keys(block)
        if keys.size == 0:
            return
        unique, inverse = np.unique(keys, return_inverse=True)
        slot_of_unique = np.fromiter(
            (self._slot(int(key)) for key in unique), dtype=np.int64, count=unique.size
        )
        slots = slot_of_unique[inverse]
        flat = self.sums.reshape(-1)
        np.add.at(flat, slots * _COLUMNS + columns, torques)
        np.add.at(flat, slots * _COLUMNS + columns + 1, 1.0)

    def _slot(self, key: int) -> int:
        slot = self.slots.get(key)
        if slot is None:
            slot = self.slots[key] = len(self.slots)
            if slot >= self.sums.shape[0]:
                grown = np.zeros((self.sums.shape[0] * 2, _COLUMNS))
                grown[: self.sums.shape[0]] = self.sums
                self.sums = grown
        return slot

    def decay(self, factor: float) -> None:
        self.sums *= factor

    def friction(self, min_frames: float) -> dict[int, tuple[float, float]]:
        """Per cell key with enough frames both ways: (friction N·m, weight)."""
        out: dict[int, tuple[float, float]] = {}
        sums = self.sums
        for key, slot in self.slots.items():
            fwd_sum, fwd_n, back_sum, back_n = sums[slot]
            if fwd_n >= min_frames and back_n >= min_frames:
                out[key] = ((fwd_sum / fwd_n - back_sum / back_n) / 2.0, min(fwd_n, back_n))
        return out

    def to_state(self) -> dict[str, object]:
        keys = list(self.slots)
        rows = [self.sums[self.slots[key]].tolist() for key in keys]
        return {"keys": keys, "sums": rows}

    @classmethod
    def from_state(cls, settings: HealthSettings, state: dict[str, object]) -> CellTable:
        table = cls(settings)
        keys = [int(k) for k in state["keys"]]  # type: ignore[attr-defined]
        rows = np.array(state["sums"], dtype=np.float64).reshape(-1, _COLUMNS)
        table.slots = {key: i for i, key in enumerate(keys)}
        table.sums = np.zeros((max(64, len(keys) * 2), _COLUMNS))
        table.sums[: len(keys)] = rows
        return table


def joint_of(key: int) -> int:
    return key // (_BANDS * _POSITIONS * _SPEEDS)


def friction_excess_percent(
    recent: CellTable, baseline: CellTable, joints: int, settings: HealthSettings
) -> list[float | None]:
    """Each joint's friction against its baseline in %, over the cells both share; ``None``
    where they share none (a joint that does not move, a temperature never seen in the
    baseline).

    The change ``Σ w·(F_now − F_base)`` is exact wherever the two directions of a cell are the
    same motion mirrored (and cancels what is not friction wherever the frames are the same);
    the reference it is a percentage of is the baseline's friction per °/s (the median over
    its cells, robust to the cells whose two directions come from different moves) times each
    shared cell's speed."""
    now = recent.friction(settings.min_cell_frames)
    base = baseline.friction(settings.min_cell_frames)
    per_speed: list[list[float]] = [[] for _ in range(joints)]
    for key, (friction_nm, _) in base.items():
        per_speed[joint_of(key)].append(friction_nm / _speed_of(key, settings))
    slope = [float(np.median(values)) if values else 0.0 for values in per_speed]
    excess = [0.0] * joints
    reference = [0.0] * joints
    for key, (friction_nm, weight) in now.items():
        base_cell = base.get(key)
        if base_cell is None:
            continue
        joint = joint_of(key)
        excess[joint] += weight * (friction_nm - base_cell[0])
        reference[joint] += weight * slope[joint] * _speed_of(key, settings)
    return [100.0 * e / r if r > 1e-9 else None for e, r in zip(excess, reference, strict=True)]


def _speed_of(key: int, settings: HealthSettings) -> float:
    return (key % _SPEEDS + 0.5) * settings.speed_bin_deg_s
