"""Layer: service. The robot's own clock for its frames, read from their T→O sequence numbers.

A frame's receive time says when the scanner's kernel took the packet, not when the robot
measured its values: on a loaded host the producer (a robot, the emulator) sends late packets
in bursts, so one 10 ms spacing arrives as 20-110 ms and the next as ~0 ms (87 of 1886 spacings
off by more than a millisecond in a scan beside CPU burners), and the health engine, which
takes its samples' spacings as whole periods, read accelerations and frictions off by tens of
per cent. Each T→O packet carries the producer's 32-bit encapsulation sequence number, raised
by one per packet it produces at the connection's T→O API (CIP Vol 2 §3-4.1): a frame's time on
the producer's clock is ``anchor + (sequence - anchor sequence) × API``.

``ProducerClock.times`` turns a block's receive times and sequence numbers into those times:

- The counter is unwrapped across its 32 bits (steps in half-range arithmetic, as
  ``enip.sequence`` compares them).
- **The anchor** of a frame is the earliest-arriving of it and the frames after it: a packet
  may arrive late, never early, so of ``receive time - (sequence × API)`` (its lag) the least
  is the one closest to the producer's instant (most packets arrive on time even under load),
  and a frame late in a burst takes the lag of the on-time frames after it. The least of the
  frames *after* a frame, not of the whole run, because the lag rises for good when the
  producer sends fewer packets than its clock counts periods: one that skips packets without
  counting them (the emulator after a stalled loop skips the missed packets on its grid,
  docs/emulator.md) or whose clock runs slower than its API (a crystal's 50 ppm: 0.18 s an
  hour). The frames after such a step take the new lag from it, so the spacing across a skip is
  its whole periods and the producer times never drift from the receive times; fitting the
  producer's period instead would leave every skip's spacing wrong. A block's last
  ``TAIL_S`` have too few frames after them to tell a lasting rise from a burst of lateness:
  they keep the lag before them (a rise among them is taken at the next block's start). A
  frame late by more than a skip that follows it cannot be told from one on time after the
  skip: it takes the skip's lag (one spacing moved, not every later one).
- **A new anchor** (a new run) where the sequence goes backwards or repeats (a new connection
  restarts its count), or a step of the sequence and the receive times' step disagree by more
  than ``JUMP_S`` (a new connection whose count happens to run on, a jump of the counter, a
  producer stalled for long): spacings across it are wrong either way, and a gap of a second
  is where the engine's samples stop anyway (``health.samples.MAX_GAP_S``).
- **No sequence** (a frame without one, no API known): the receive times, as before.

The producer times are never later than the receive times and earlier by a frame's lateness
(the frames on time: by nothing, or what a rise in a block's tail left): the cycle meter's
boundaries (receive times of frames) are mapped to the producer times of those frames
(``monitor.RobotHealth``), so the engine cuts each cycle at the same frames as before.
"""

from __future__ import annotations

import math
from typing import Final, NamedTuple

import numpy as np

from cobot_hmi.health.frames import FloatArray, IntArray

SEQUENCE_MASK: Final = 0xFFFF_FFFF
SEQUENCE_HALF: Final = 0x8000_0000
JUMP_S: Final = 1.0
"""A sequence step whose time (steps × API) differs from the receive times' step by more than
this starts a new run: longer than any lateness a loaded host showed (110 ms), and as long as
the engine's ``MAX_GAP_S``."""
TAIL_S: Final = 0.25
"""A block's frames this close to its end keep the lag before them: longer than the longest
burst of lateness a loaded host showed (110 ms)."""


class _Last(NamedTuple):
    sequence: int
    received_s: float
    producer_s: float


class ProducerClock:
    """One connection's producer times, block by block (see the module docstring)."""

    __slots__ = ("_last", "runs")

    def __init__(self) -> None:
        self._last: _Last | None = None
        """The last frame's raw sequence number, receive time and producer time."""
        self.runs = 0
        """Runs begun (the first frames, reconnections, jumps of the sequence)."""

    def times(
        self, received_s: FloatArray, sequences: IntArray | None, api_s: float | None
    ) -> FloatArray:
        """The block's frames' times on the producer's clock: ``received_s`` (their receive
        times, in order), ``sequences`` their T→O sequence numbers (None, or any negative: not
        known), ``api_s`` the connection's T→O packet interval (None: not known)."""
        n = received_s.size
        if n == 0:
            return received_s
        if sequences is None or api_s is None or not api_s > 0.0 or int(sequences.min()) < 0:
            self._last = None
            return received_s
        steps = np.empty(n, dtype=np.int64)
        steps[1:] = (sequences[1:] - sequences[:-1]) & SEQUENCE_MASK
        received_steps_s = np.empty(n, dtype=np.float64)
        received_steps_s[1:] = np.diff(received_s)
        last = self._last
        if last is not None:
            steps[0] = (sequences[0] - last.sequence) & SEQUENCE_MASK
            received_steps_s[0] = received_s[0] - last.received_s
        new_run = (
            (steps == 0)
            | (steps >= SEQUENCE_HALF)
            | (np.abs(steps * api_s - received_steps_s) > JUMP_S)
        )
        if last is None:
            new_run[0] = True
        # Elapsed producer time from the block's start, continuous over new runs (their own
        # step is left out): within a run a frame's time is its run's anchor + elapsed.
        elapsed_s = np.cumsum(np.where(new_run, 0, steps)) * api_s
        lag_s = received_s - elapsed_s
        tail = max(1, math.ceil(TAIL_S / api_s))
        producer_s = np.empty(n, dtype=np.float64)
        starts = np.flatnonzero(new_run).tolist()
        bounds = [0, *starts] if not starts or starts[0] != 0 else starts
        for k, start in enumerate(bounds):
            end = bounds[k + 1] if k + 1 < len(bounds) else n
            lag = lag_s[start:end]
            # Each frame's anchor: the least lag of it and every later frame of its run.
            anchor_s = np.minimum.accumulate(lag[::-1])[::-1]
            held = max(0, lag.size - tail)  # the frames before the tail
            if held:
                level_s = float(anchor_s[held - 1])
            elif start == 0 and last is not None and not new_run[0]:
                level_s = min(last.producer_s, float(lag.min()))  # the run's anchor goes on
            else:
                level_s = float(lag.min())
            anchor_s[held:] = level_s
            if start != 0 or last is None or new_run[0]:
                self.runs += 1
            producer_s[start:end] = anchor_s + elapsed_s[start:end]
        self._last = _Last(int(sequences[-1]), float(received_s[-1]), float(producer_s[-1]))
        return producer_s
