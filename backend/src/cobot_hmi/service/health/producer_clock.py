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
- **The anchor** is the earliest-arriving frame: a packet may arrive late, never early, so of
  ``receive time - (sequence × API)`` the least over a block is the one closest to the
  producer's instant (most packets of a block arrive on time even under load). It is taken
  again, per block, when a block's least is lower (an earlier anchor was late) or higher by
  more than ``RAISE_S`` (see there); each such move changes one spacing, at the block's start.
- **A new anchor** (a new run) where the sequence goes backwards or repeats (a new connection
  restarts its count), or a step of the sequence and the receive times' step disagree by more
  than ``JUMP_S`` (a new connection whose count happens to run on, a jump of the counter, a
  producer stalled for long): spacings across it are wrong either way, and a gap of a second
  is where the engine's samples stop anyway (``health.samples.MAX_GAP_S``).
- **No sequence** (a frame without one, no API known): the receive times, as before.

The producer times are never later than the receive times and, outside a new run's first
block, never earlier by more than a frame's lateness plus ``RAISE_S``: the cycle meter's
boundaries (receive times of frames) are mapped to the producer times of those frames
(``monitor.RobotHealth``), so the engine cuts each cycle at the same frames as before.
"""

from __future__ import annotations

from typing import Final, NamedTuple

import numpy as np

from cobot_hmi.health.frames import FloatArray, IntArray

SEQUENCE_MASK: Final = 0xFFFF_FFFF
SEQUENCE_HALF: Final = 0x8000_0000
JUMP_S: Final = 1.0
"""A sequence step whose time (steps × API) differs from the receive times' step by more than
this starts a new run: longer than any lateness a loaded host showed (110 ms), and as long as
the engine's ``MAX_GAP_S``."""
RAISE_S: Final = 0.1
"""How far the producer times may fall behind the receive times (the block's least lag) before
the anchor is taken again. They fall behind when the producer's clock runs slower than its
nominal API (a crystal's 50 ppm: 0.18 s an hour), or when it skips packets without counting
them (the emulator after a stalled loop skips missed packets on its grid, docs/emulator.md):
without a bound the producer times would drift away from the receive times over hours and the
cycle boundaries with them. Re-anchoring on a bound, rather than fitting the producer's real
period, keeps every spacing within a run exactly whole APIs (what the engine snaps to) at the
cost of one spacing changed per re-anchoring; ten packets at 10 ms, so it is rare."""


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
        """Anchors taken anew (the first, reconnections, jumps, raises past ``RAISE_S``)."""

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
        producer_s = np.empty(n, dtype=np.float64)
        starts = np.flatnonzero(new_run).tolist()
        bounds = [0, *starts] if not starts or starts[0] != 0 else starts
        for k, start in enumerate(bounds):
            end = bounds[k + 1] if k + 1 < len(bounds) else n
            least_s = float(lag_s[start:end].min())
            if start == 0 and last is not None and not new_run[0]:
                anchor_s = last.producer_s  # the run goes on: its anchor unless moved
                if least_s > anchor_s + RAISE_S:
                    anchor_s = least_s
                    self.runs += 1
                elif least_s < anchor_s:  # a frame came before its time: the anchor was late
                    anchor_s = least_s
            else:
                anchor_s = least_s
                self.runs += 1
            producer_s[start:end] = anchor_s + elapsed_s[start:end]
        self._last = _Last(int(sequences[-1]), float(received_s[-1]), float(producer_s[-1]))
        return producer_s
