"""Layer: health (pure). Imports ``health.frames`` and ``health.health_settings``.

Friction: what a joint needs at the same position and speed beyond its baseline, in the same
band of motor temperature. Samples (``health.samples``: distinct measurements, each with its
joint acceleration; one straddling a change of acceleration left out) are put in cells (joint,
temperature band, position bin, speed bin, direction). In each the torque is fitted by least
squares as ``τ = α + β·x + γ·y`` (``x`` the position within the bin, ``y`` the acceleration),
so which samples of the motion fall in the cell (the frames' phase against the motion, the
controller's 100 ms refresh) does not move ``α``, the torque at the cell's centre. Gravity and
inertia at a cell are what they were in the baseline (the same program, the same payload);
friction acts against the motion: ``sign(v)·(α_now − α_base)`` is how much more friction the
joint has there. The reference the change is a percentage of is the baseline's friction per
°/s (``k``, the median over the cells it saw both ways, where friction is
``(α_forward − α_back)/2``, gravity being even in the direction and friction odd) times each
cell's speed: a joint's figure is ``Σ w·sign·Δα / Σ w·k·v`` over the cells it shares with its
baseline, ``w`` the fewer samples of the two.

Cells are sparse (a program visits a few hundred of the millions possible): a key per cell, a
slot per key, sums in numpy arrays indexed by slot.
"""

from __future__ import annotations

import numpy as np

from cobot_hmi.health.frames import FloatArray, FrameBlock, IntArray
from cobot_hmi.health.health_settings import HealthSettings

_BANDS = 100  # temperature bands from −40 °C
_POSITIONS = 100  # position bins from −500°
_SPEEDS = 100
_PER_JOINT = _BANDS * _POSITIONS * _SPEEDS
_TERMS = 9
"""Per direction: n, Σx, Σy, Σx², Σy², Σxy, Στ, Στx, Στy (x the position in the bin, −½ to ½;
y the acceleration in hundreds of °/s²)."""
_ACCELERATION_SCALE = 100.0
_COLUMNS = 2 * _TERMS  # forward, then back
_TERM_OFFSETS = np.arange(_TERMS)
_LARGE_TABLE = 65_536
"""Sums (cells × columns) from which binning a few samples over the cells they touch
(``np.unique``, ~20 µs) costs less than binning them over the whole table."""
_RIDGE = 1e-3
"""Keeps a fit whose samples do not spread in position or acceleration to its mean there."""
MIN_SHARED_SAMPLES = 20.0
"""Fewer samples shared with the baseline than this give no figure."""


def _bin(values: FloatArray, width: float, count: int) -> IntArray:
    """``floor(values / width)`` as integers within 0 … count − 1."""
    bins = np.floor(values * (1.0 / width)).astype(np.int64)
    # minimum/maximum rather than clip: the same result, without clip's per-call overhead.
    np.maximum(bins, 0, out=bins)
    np.minimum(bins, count - 1, out=bins)
    return bins


class CellTable:
    """Per cell and direction: the sums of its torque fit (see the module docstring)."""

    def __init__(self, settings: HealthSettings) -> None:
        self._settings = settings
        self.slots: dict[int, int] = {}
        self.sums: FloatArray = np.zeros((64, _COLUMNS))
        self._sorted: tuple[IntArray, IntArray] = (
            np.zeros(0, dtype=np.int64),
            np.zeros(0, dtype=np.int64),
        )
        self._fits: tuple[float, tuple[IntArray, FloatArray, FloatArray]] | None = None
        """The last ``fits`` and its minimum, until the sums change (a baseline's never do
        once learned, and a report asks for them every time)."""

    def add(
        self, block: FrameBlock, acceleration_deg_s2: FloatArray, *, steady_only: bool = False
    ) -> None:
        """Distinct samples (``DistinctSamples``) and their joint accelerations (NaN: a sample
        to leave out)."""
        s = self._settings
        velocity = block.velocity_deg_s
        speed = np.abs(velocity)
        moving = (speed >= s.min_speed_deg_s) & block.servo_on[:, None]
        moving &= np.isfinite(acceleration_deg_s2)
        if steady_only:
            moving &= np.abs(acceleration_deg_s2) <= s.jerk_tolerance_deg_s2
        rows, joint = np.nonzero(moving)
        if rows.size == 0:
            return
        self._fits = None
        # Only the moving samples' values, as flat vectors.
        band = _bin(block.temperature_c[rows, joint] + 40.0, s.temperature_band_c, _BANDS)
        scaled = (block.position_deg[rows, joint] + 500.0) / s.position_bin_deg
        position = _bin(scaled, 1.0, _POSITIONS)
        speed_bin = _bin(speed[rows, joint], s.speed_bin_deg_s, _SPEEDS)
        keys = ((joint * _BANDS + band) * _POSITIONS + position) * _SPEEDS + speed_bin
        x = scaled - position - 0.5
        y = acceleration_deg_s2[rows, joint] / _ACCELERATION_SCALE
        torque = block.torque_nm[rows, joint]
        terms = np.empty((x.size, _TERMS))
        terms[:, 0] = 1.0
        columns: tuple[FloatArray, ...] = (
            x,
            y,
            x * x,
            y * y,
            x * y,
            torque,
            torque * x,
            torque * y,
        )
        for column, value in enumerate(columns, start=1):
            terms[:, column] = value
        base = self._slots_of(keys) * _COLUMNS + np.where(velocity[rows, joint] > 0.0, 0, _TERMS)
        flat = self.sums.reshape(-1)
        if flat.size < _LARGE_TABLE or base.size * _TERMS * 4 >= flat.size:
            index = (base[:, None] + _TERM_OFFSETS).ravel()
            flat += np.bincount(index, weights=terms.ravel(), minlength=flat.size)
            return
        # A few samples (a second's block at a 100 ms refresh) against a large table (months of
        # temperature bands): the sums binned over the cells they touch only, not over the
        # whole table (the same sums, each cell's samples added in the same order).
        touched, inverse = np.unique(base, return_inverse=True)
        index = (inverse.reshape(-1)[:, None] * _TERMS + _TERM_OFFSETS).ravel()
        partial = np.bincount(index, weights=terms.ravel(), minlength=touched.size * _TERMS)
        flat[(touched[:, None] + _TERM_OFFSETS).ravel()] += partial

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
        self._fits = None

    def fits(self, min_samples: float) -> tuple[IntArray, FloatArray, FloatArray]:
        """Every cell's key (sorted), and per direction (forward, back) its torque at the
        centre ``α`` (N·m; NaN with fewer than ``min_samples``) and its samples (arrays the
        caller must not change: they are kept for the next call)."""
        if self._fits is not None and self._fits[0] == min_samples:
            return self._fits[1]
        keys, slots = self._sorted
        sums = self.sums[slots]
        alphas, counts = [], []
        for terms in (sums[:, :_TERMS], sums[:, _TERMS:]):
            enough = terms[:, 0] >= min_samples
            alpha = np.full(terms.shape[0], np.nan)
            alpha[enough] = _intercepts(terms[enough])
            alphas.append(alpha)
            counts.append(terms[:, 0])
        fits = (keys, np.stack(alphas, axis=1), np.stack(counts, axis=1))
        self._fits = (min_samples, fits)
        return fits

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


def _intercepts(terms: FloatArray) -> FloatArray:
    """Each row's least-squares ``α`` of ``τ = α + β·x + γ·y`` from its sums (ridge on β, γ)."""
    n, sx, sy, sxx, syy, sxy, st, stx, sty = terms.T
    ridge = _RIDGE * n
    matrix = np.stack(
        [
            np.stack([n, sx, sy], axis=1),
            np.stack([sx, sxx + ridge, sxy], axis=1),
            np.stack([sy, sxy, syy + ridge], axis=1),
        ],
        axis=1,
    )
    solution = np.linalg.solve(matrix, np.stack([st, stx, sty], axis=1)[:, :, None])
    intercepts: FloatArray = solution[:, 0, 0]
    return intercepts


MIN_REFERENCE_CELLS = 3
"""A friction per °/s needs at least this many cells seen both ways."""


def friction_per_speed(cells: CellTable, joints: int, settings: HealthSettings) -> FloatArray:
    """Per joint: the friction per °/s, the median over the cells seen both ways (NaN for a
    joint seen so in fewer than ``MIN_REFERENCE_CELLS``)."""
    keys, alpha, _ = cells.fits(settings.min_cell_frames)
    both = np.all(np.isfinite(alpha), axis=1)
    per_speed = (alpha[both, 0] - alpha[both, 1]) / 2.0 / _speed_of(keys[both], settings)
    joint = keys[both] // _PER_JOINT
    return np.array(
        [
            np.median(per_speed[joint == j])
            if np.count_nonzero(joint == j) >= MIN_REFERENCE_CELLS
            else np.nan
            for j in range(joints)
        ]
    )


def friction_excess_percent(
    recent: CellTable,
    baseline: CellTable,
    slope: FloatArray,
    settings: HealthSettings,
) -> list[float | None]:
    """Each joint's friction against its baseline in % (see the module docstring); ``None``
    where they share too few samples (a joint that hardly moves, a temperature never seen in
    the baseline) or the baseline never saw the joint move both ways at one place."""
    joints = slope.size
    now_keys, now_alpha, now_n = recent.fits(settings.min_cell_frames)
    base_keys, base_alpha, base_n = baseline.fits(settings.min_cell_frames)
    shared = np.isin(now_keys, base_keys, assume_unique=True)
    at = np.searchsorted(base_keys, now_keys[shared])
    keys = now_keys[shared]
    delta = (now_alpha[shared] - base_alpha[at]) * np.array([1.0, -1.0])
    weight = np.minimum(now_n[shared], base_n[at])
    usable = np.isfinite(delta)
    weight = np.where(usable, weight, 0.0)
    delta = np.where(usable, delta, 0.0)
    joint = np.repeat((keys // _PER_JOINT)[:, None], 2, axis=1)
    speed = np.repeat(_speed_of(keys, settings)[:, None], 2, axis=1)
    excess = np.bincount(joint.ravel(), weights=(weight * delta).ravel(), minlength=joints)
    samples = np.bincount(joint.ravel(), weights=weight.ravel(), minlength=joints)
    reference = slope * np.bincount(
        joint.ravel(), weights=(weight * speed).ravel(), minlength=joints
    )
    return [
        100.0 * float(e) / float(r)
        if np.isfinite(r) and r > 1e-9 and n >= MIN_SHARED_SAMPLES
        else None
        for e, r, n in zip(excess, reference, samples, strict=True)
    ]


def _speed_of(keys: IntArray, settings: HealthSettings) -> FloatArray:
    bins = (keys % _SPEEDS).astype(np.float64)
    speeds: FloatArray = (bins + 0.5) * settings.speed_bin_deg_s
    return speeds
