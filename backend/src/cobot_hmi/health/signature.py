"""Layer: health (pure). Imports ``health.frames``.

The torque signature of a cycle: each joint's torque over the cycle, resampled to a fixed
number of points of the cycle's phase (0 at its start, 1 at its end), compared with the
baseline's mean signature as an RMS deviation and with the baseline's torque distribution as a
Wasserstein-1 distance (the mean gap between the two quantile functions), both normalised by
the joint's RMS torque in the baseline, in %.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from cobot_hmi.health.frames import FloatArray, FrameBlock

QUANTILES = np.linspace(0.0, 1.0, 101)


def resample(block: FrameBlock, start_s: float, end_s: float, points: int) -> FloatArray:
    """``(points, joints)``: the torque at evenly spaced phases of the cycle."""
    phase = (block.time_s - start_s) / (end_s - start_s)
    grid = (np.arange(points) + 0.5) / points
    torque = block.torque_nm
    return np.stack([np.interp(grid, phase, torque[:, j]) for j in range(torque.shape[1])], axis=1)


def quantiles(block: FrameBlock) -> FloatArray:
    """``(101, joints)``: the torque's quantiles over the frames (linear interpolation between
    order statistics, as ``np.quantile``'s default, written out: it costs a fifth)."""
    ordered = np.sort(block.torque_nm, axis=0)
    position = QUANTILES * (ordered.shape[0] - 1)
    low = np.floor(position).astype(np.int64)
    high = np.minimum(low + 1, ordered.shape[0] - 1)
    fraction = (position - low)[:, None]
    result: FloatArray = ordered[low] + (ordered[high] - ordered[low]) * fraction
    return result


class SignatureDeviation(NamedTuple):
    rms_percent: FloatArray
    distribution_percent: FloatArray


def compare(
    signature: FloatArray,
    distribution: FloatArray,
    base_signature: FloatArray,
    base_distribution: FloatArray,
) -> SignatureDeviation:
    scale = np.sqrt(np.mean(base_signature**2, axis=0))
    scale = np.where(scale > 1e-6, scale, 1.0)
    rms = np.sqrt(np.mean((signature - base_signature) ** 2, axis=0)) / scale
    wasserstein = np.mean(np.abs(distribution - base_distribution), axis=0) / scale
    return SignatureDeviation(100.0 * rms, 100.0 * wasserstein)
