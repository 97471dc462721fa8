"""The health engine's accelerations at the controller's 100 ms refresh, when a refresh goes out a
few frames late: the robot measures on its own 100 ms grid (the emulator too,
test_emulator_refresh_grid), but the emulator's read of its robot comes when its loop wakes,
late on a loaded host, so a refresh reaches the frames one to four RPIs late. The engine snapped
the spacings of distinct samples to whole *frame* periods of their receive times, which carried
the lateness (a 100 ms spacing read as 130 ms, the next as 70 ms): accelerations some 30 % wrong
and kept (the slopes before and after a sample were wrong alike). It now snaps them to whole
periods of the robot's refresh (the median spacing of its distinct samples), so the frames in
which a refresh first appears do not move its samples' accelerations."""

from __future__ import annotations

import itertools
import math

import numpy as np

from cobot_hmi.health import FrameBlock
from cobot_hmi.health.health_settings import HealthSettings
from cobot_hmi.health.samples import DistinctSamples

RPI_S = 0.01
REFRESH_FRAMES = 10
"""100 ms at a 10 ms RPI."""
LATE_FRAMES = (0, 3, 1, 4, 2, 0, 2, 4, 1, 3, 0, 0, 4)
"""How many frames after its instant each refresh first appears (under a refresh period)."""
BLOCKS = 4
FRAMES_PER_BLOCK = 100
JOINTS = 6


def _values(refresh: int) -> tuple[list[float], list[float], list[float]]:
    """Position, velocity and torque of every joint at the refresh's instant: a smooth motion
    (velocity 30 sin t °/s, accelerations up to 30 °/s², within the engine's jerk tolerance over
    a refresh)."""
    t = refresh * REFRESH_FRAMES * RPI_S
    phases = [0.3 * j for j in range(JOINTS)]
    position = [-30.0 * math.cos(t + p) for p in phases]
    velocity = [30.0 * math.sin(t + p) for p in phases]
    torque = [5.0 + 0.1 * v for v in velocity]
    return position, velocity, torque


def _accelerations(late_frames: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Every block's distinct samples' refresh indices and accelerations, the frames received
    on their RPI grid, each refresh first in the frame ``late`` frames after its instant."""
    appears = [
        m * REFRESH_FRAMES + late
        for m, late in zip(range(BLOCKS * FRAMES_PER_BLOCK), itertools.cycle(late_frames))
    ]
    samples = DistinctSamples()
    tolerance = HealthSettings().jerk_tolerance_deg_s2
    indices, accelerations = [], []
    refresh = 0
    for b in range(BLOCKS):
        frames = range(b * FRAMES_PER_BLOCK, (b + 1) * FRAMES_PER_BLOCK)
        shown = []
        for k in frames:
            while appears[refresh + 1] <= k:
                refresh += 1
            shown.append(refresh)
        rows = [_values(m) for m in shown]
        n = len(rows)
        block = FrameBlock(
            np.array([k * RPI_S for k in frames]),
            np.array([r[0] for r in rows]),
            np.array([r[1] for r in rows]),
            np.array([r[2] for r in rows]),
            np.zeros((n, JOINTS)),
            np.zeros((n, JOINTS)),
            np.full((n, JOINTS), 25.0),
            np.full(n, 1, dtype=np.int64),
            np.ones(n, dtype=np.bool_),
        )
        distinct, acceleration = samples.take(block, tolerance)
        indices += [shown[np.searchsorted(block.time_s, t)] for t in distinct.time_s]
        accelerations.append(acceleration)
    return np.array(indices), np.concatenate(accelerations)


def test_a_refresh_sent_frames_late_keeps_its_samples_accelerations() -> None:
    on_time_index, on_time = _accelerations((0,))
    late_index, late = _accelerations(LATE_FRAMES)
    assert list(late_index) == list(on_time_index)  # the same refreshes, in other frames
    both = np.isfinite(on_time) & np.isfinite(late)
    worst = float(np.max(np.abs(late[both] - on_time[both])))
    assert worst < 1e-6, f"accelerations moved by up to {worst:.2f} °/s² by the refreshes' lateness"
    # Most samples get an acceleration, the same either way (none left out for the lateness).
    assert np.isfinite(on_time).sum() > 0.8 * on_time.size
    assert both.sum() == np.isfinite(on_time).sum()
