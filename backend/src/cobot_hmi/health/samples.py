"""Layer: health (pure). Imports ``health.frames``.

The distinct measurements among the frames, and each joint's acceleration at them. The
controller refreshes its monitoring values about every 100 ms whatever the RPI
(docs/emulator.md), so at a 10 ms RPI nine frames in ten repeat the one before: a frame whose
joint positions, velocities and torques all equal the previous frame's is the same measurement
again, and is left out where samples are counted and fitted (friction). Accelerations are the
central differences of the velocities of successive distinct samples, across blocks (the last
sample of a block is kept), and not across a gap of more than ``MAX_GAP_S``; a sample whose
slopes before and after disagree straddles a change of acceleration and gets none.
"""

from __future__ import annotations

from collections import deque
from typing import Final

import numpy as np

from cobot_hmi.health.frames import FloatArray, FrameBlock

MAX_GAP_S: Final = 1.0
REFRESH_SPACINGS: Final = 101
"""How many of the latest spacings of distinct samples (in whole frame periods) the robot's
refresh period is read from: ten seconds at the controller's 100 ms."""


class DistinctSamples:
    """Keeps the last distinct sample between blocks (see the module docstring)."""

    def __init__(self) -> None:
        self.last: tuple[float, FloatArray, FloatArray, FloatArray] | None = None
        """Time, positions, velocities, torques of the last distinct sample."""
        self.refresh_frames: deque[int] = deque(maxlen=REFRESH_SPACINGS)
        """The latest spacings of distinct samples within blocks, in whole frame periods (not
        saved: the first blocks after a restore read it again)."""

    def take(
        self, block: FrameBlock, jerk_tolerance_deg_s2: float
    ) -> tuple[FrameBlock, FloatArray]:
        """The block's distinct samples and the joints' accelerations at them (°/s²): the mean
        of the velocity's slopes before and after each sample, NaN where the two differ by more
        than the tolerance (and 10 %: the sample straddles a change of acceleration) or one is
        missing (the first sample after a gap, the block's last)."""
        values = np.concatenate([block.position_deg, block.velocity_deg_s, block.torque_nm], axis=1)
        changed = np.empty(values.shape[0], dtype=np.bool_)
        if changed.size:
            np.any(values[1:] != values[:-1], axis=1, out=changed[1:])
            changed[0] = self.last is None or bool(
                np.any(values[0] != np.concatenate(self.last[1:]))
            )
        distinct = block.take(changed)
        if len(distinct) == 0:
            return distinct, np.zeros_like(distinct.velocity_deg_s)
        times, velocity = distinct.time_s, distinct.velocity_deg_s
        if self.last is not None and times[0] - self.last[0] <= MAX_GAP_S:
            times = np.concatenate([[self.last[0]], times])
            velocity = np.concatenate([self.last[2][None, :], velocity])
        else:  # no sample before the first: its slope before is unknown
            times = np.concatenate([[times[0] - 1.0], times])
            velocity = np.concatenate([np.full((1, velocity.shape[1]), np.nan), velocity])
        spacing_s = self._snapped(np.diff(times), block.time_s, distinct.time_s)
        slopes = np.diff(velocity, axis=0) / spacing_s[:, None]
        after = np.concatenate([slopes[1:], np.full((1, slopes.shape[1]), np.nan)])
        spread = np.abs(after - slopes)
        limit = jerk_tolerance_deg_s2 + 0.1 * np.maximum(np.abs(after), np.abs(slopes))
        acceleration: FloatArray = np.where(spread <= limit, (after + slopes) / 2.0, np.nan)
        self.last = (
            float(distinct.time_s[-1]),
            distinct.position_deg[-1].copy(),
            distinct.velocity_deg_s[-1].copy(),
            distinct.torque_nm[-1].copy(),
        )
        return distinct, acceleration

    def _snapped(
        self, spacing_s: FloatArray, frame_times_s: FloatArray, sample_times_s: FloatArray
    ) -> FloatArray:
        """Sample spacings as whole numbers of the robot's data period.

        The times are when the frames were received: a few ms of jitter on a loaded host
        against a 10 ms period made the accelerations some 20 % wrong and the friction fits
        with them (a healthy J2 read +70 %). The robot measures on its own clock, so a spacing
        is a whole number of its periods: the frame period (the block's median interval) when
        every frame is a fresh measurement, else the period its monitoring values refresh at
        (read from the latest spacings of distinct samples: 100 ms at the controller's
        refresh). A refresh goes out in the first frame after it: one sent a few frames late
        (an emulator whose read of its robot came late on a loaded host) moved its sample by
        whole frame periods, so snapped to frame periods its spacings were wrong by the
        lateness. A block of one frame has no period and keeps its spacing."""
        if frame_times_s.size < 2:
            return spacing_s
        period_s = float(np.median(np.diff(frame_times_s)))
        if not period_s > 0.0:
            return spacing_s
        within = np.round(np.diff(sample_times_s) / period_s).astype(np.int64)
        self.refresh_frames.extend(within.tolist())
        if self.refresh_frames:
            period_s *= self._refresh_period_frames()
        snapped: FloatArray = np.maximum(np.round(spacing_s / period_s), 1.0) * period_s
        return snapped

    def _refresh_period_frames(self) -> int:
        """The robot's refresh period in whole frame periods: the mean of the latest spacings
        near their median (a refresh sent late lengthens one spacing and shortens the next by
        as much, so their mean keeps the period where a median of a few may not; a pause of the
        arm, whose samples repeat, is not a spacing of the refresh)."""
        spacings = np.array(self.refresh_frames, dtype=np.float64)
        middle = float(np.median(spacings))
        near = spacings[(spacings >= 0.5 * middle) & (spacings <= 1.5 * middle)]
        return max(1, round(float(np.mean(near)))) if near.size else 1

    def to_state(self) -> list[object] | None:
        if self.last is None:
            return None
        time_s, *rows = self.last
        return [time_s, *(row.tolist() for row in rows)]

    def restore(self, state: object) -> None:
        if state is None:
            self.last = None
            return
        assert isinstance(state, list)
        time_s, position, velocity, torque = state
        self.last = (
            float(time_s),
            np.array(position, dtype=np.float64),
            np.array(velocity, dtype=np.float64),
            np.array(torque, dtype=np.float64),
        )
