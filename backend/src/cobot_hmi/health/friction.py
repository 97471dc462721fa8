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
_PER_JOINT = _BANDS * _POSITIONS * _SPEEDS


def _bin(values: FloatArray, width: float, count: int) -> IntArray:
    """``floor(values / width)`` as integers within 0 … count − 1."""
    bins = np.floor(values * (1.0 / width)).astype(np.int64)
    np.clip(bins, 0, count - 1, out=bins)
    return bins


class CellTable:
    """Per cell: forward and backward torque sums and frame counts (see the module docstring)."""

    def __init__(self, settings: HealthSettings) -> None:
        self._settings = settings
        self.slots: dict[int, int] = {}
        self.sums: FloatArray = np.zeros((64, _COLUMNS))
        self._sorted: tuple[IntArray, IntArray] = (
            np.zeros(0, dtype=np.int64),
            np.zeros(0, dtype=np.int64),
        )

    def keys(self, block: FrameBlock) -> tuple[IntArray, IntArray, FloatArray]:
        """Each moving frame's cell key, direction column (0 forward, 2 back) and torque."""
        s = self._settings
        velocity = block.velocity_deg_s
        speed = np.abs(velocity)
        moving = (speed >= s.min_speed_deg_s) & block.servo_on[:, None]
        rows, joint = np.nonzero(moving)
        # Only the moving frames' values, as flat vectors: a third of the work on a cycle.
        band = _bin(block.temperature_c[rows, joint] + 40.0, s.temperature_band_c, _BANDS)
        position = _bin(block.position_deg[rows, joint] + 500.0, s.position_bin_deg, _POSITIONS)
        speed_bin = _bin(speed[rows, joint], s.speed_bin_deg_s, _SPEEDS)
        key = ((joint * _BANDS + band) * _POSITIONS + position) * _SPEEDS + speed_bin
        column = np.where(velocity[rows, joint] > 0.0, 0, 2)
        return key, column, block.torque_nm[rows, joint]

    def add(self, block: FrameBlock) -> None:
        keys, columns, torques = self.keys(block)
        if keys.size == 0:
            return
        slots = self._slots_of(keys)
        index = slots * _COLUMNS + columns
        size = self.sums.size
        flat = self.sums.reshape(-1)
        flat += np.bincount(index, weights=torques, minlength=size)
        flat[1:] += np.bincount(index, minlength=size)[:-1]  # the frame counts, one column on

    def _slots_of(self, keys: IntArray) -> IntArray:
        """Each key's slot: found in the sorted known keys at numpy speed; a key never seen
        (a new cell: the first cycles, then rarely) gets a slot of its own."""
        known, known_slots = self._sorted
        position = np.minimum(np.searchsorted(known, keys), max(known.size - 1, 0))
        found = known.size > 0 and known[position] == keys
        if np.all(found):
            slots: IntArray = known_slots[position]
            return slots
        for key in np.unique(keys[~found]):
            self._slot(int(key))
        self._index_keys()
        return self._slots_of(keys)

    def _slot(self, key: int) -> int:
        slot = self.slots.get(key)
        if slot is None:
            slot = self.slots[key] = len(self.slots)
            if slot >= self.sums.shape[0]:
                grown = np.zeros((self.sums.shape[0] * 2, _COLUMNS))
                grown[: self.sums.shape[0]] = self.sums
                self.sums = grown
        return slot

    def _index_keys(self) -> None:
        keys = np.fromiter(self.slots.keys(), dtype=np.int64, count=len(self.slots))
        slots = np.fromiter(self.slots.values(), dtype=np.int64, count=len(self.slots))
        order = np.argsort(keys)
        self._sorted = (keys[order], slots[order])

    def decay(self, factor: float) -> None:
        self.sums *= factor

    def friction(self, min_frames: float) -> tuple[IntArray, FloatArray, FloatArray]:
        """The cells with enough frames both ways: their keys (sorted), friction (N·m) and
        weight (the fewer frames of the two directions)."""
        keys, slots = self._sorted
        sums = self.sums[slots]
        forward_n, back_n = sums[:, 1], sums[:, 3]
        ok = (forward_n >= min_frames) & (back_n >= min_frames)
        sums, forward_n, back_n = sums[ok], forward_n[ok], back_n[ok]
        friction = (sums[:, 0] / forward_n - sums[:, 2] / back_n) / 2.0
        return keys[ok], friction, np.minimum(forward_n, back_n)

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
        table._index_keys()
        return table


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
    now_keys, now_friction, weight = recent.friction(settings.min_cell_frames)
    base_keys, base_friction, _ = baseline.friction(settings.min_cell_frames)
    base_joint = base_keys // _PER_JOINT
    per_speed = base_friction / _speed_of(base_keys, settings)
    slope = np.array(
        [
            np.median(per_speed[base_joint == j]) if np.any(base_joint == j) else 0.0
            for j in range(joints)
        ]
    )
    shared = np.isin(now_keys, base_keys, assume_unique=True)
    keys, friction, weight = now_keys[shared], now_friction[shared], weight[shared]
    base_at = base_friction[np.searchsorted(base_keys, keys)]
    joint = keys // _PER_JOINT
    excess = np.bincount(joint, weights=weight * (friction - base_at), minlength=joints)
    reference = np.bincount(
        joint, weights=weight * slope[joint] * _speed_of(keys, settings), minlength=joints
    )
    return [
        100.0 * float(e) / float(r) if r > 1e-9 else None
        for e, r in zip(excess, reference, strict=True)
    ]


def _speed_of(keys: IntArray, settings: HealthSettings) -> FloatArray:
    bins = (keys % _SPEEDS).astype(np.float64)
    speeds: FloatArray = (bins + 0.5) * settings.speed_bin_deg_s
    return speeds
