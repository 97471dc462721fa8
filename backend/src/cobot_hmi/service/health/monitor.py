"""Layer: service. One robot's health engine as a consumer of its frames and cycles, off the
cyclic path.

``RobotHealth`` is a frame consumer (``robots.frame_notifier``) that runs on the health
thread (``Runs.THREAD``): on the cyclic thread a frame costs one append into its bounded queue
(``health_queue_frames``; when health falls behind the oldest frames go and are counted in the
notifier's ``dropped``, ``/metrics``' ``cobot_hmi_consumer_dropped_frames_total``), never a
wait. The health thread takes the queued frames every ``health_refresh_s`` as one block (the
engine wants at least a second's frames a block) and feeds the engine, the frames' times on the
robot's own clock (``producer_clock``: from their T→O sequence numbers at the granted API; the
receive times where those are not known); the cycle meter's cycles (``cycle`` events, heard on
the web loop, their boundaries receive times of frames) wait in ``cycles`` until the engine has
seen every frame of theirs, then end the cycle in the engine at those frames' producer times
(``ReceiveToProducer``), so a cycle holds the same frames whichever clock the block carries.
Every call into the engine holds ``lock``: the web loop asks for reports and baselines from a
worker thread of its own.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import OrderedDict, deque
from collections.abc import Callable, Sequence
from typing import Final

import numpy as np

from cobot_hmi.arms import ARMS, Arm, arm_by_name
from cobot_hmi.health import FrameBlock, HealthEngine
from cobot_hmi.health.frames import FloatArray, IntArray
from cobot_hmi.service.health.producer_clock import ProducerClock
from cobot_hmi.service.robots.frame_notifier import FrameRecord, Registration, Runs
from cobot_hmi.service.robots.robot import RobotRuntime

log = logging.getLogger(__name__)

VERDICT_RANK: Final = {"ok": 0, "watch": 1, "act": 2}
MAPPED_S: Final = 60.0
"""How far back the frames' receive and producer times are kept to map cycle boundaries: a
cycle is announced within a second or so of its end frame, and its start is the end of the
cycle before (remembered apart, ``ReceiveToProducer.ENDS``)."""


def arm_of(robot: RobotRuntime, configured: str) -> Arm:
    """The robot's arm: the ``health_arm`` setting, else the one its identity's product name
    names ("Doosan M1013 (emulated)"), else the first known arm."""
    if configured:
        return arm_by_name(configured)
    identity = robot.identity
    if identity is not None:
        for arm in ARMS:
            if arm.name in identity.product_name.upper():
                return arm
    return ARMS[0]


def worst_verdict(joints: Sequence[dict[str, object]]) -> str:
    """The worst of the joints' verdicts (ok < watch < act)."""
    words = [str(j.get("verdict", "ok")) for j in joints]
    return max(words, key=lambda w: VERDICT_RANK.get(w, 0), default="ok")


def granted_api_s(robot: RobotRuntime) -> float | None:
    """The robot's connection's T→O packet interval (s), None between connections."""
    api_us = robot.link.t2o_api_us
    return api_us / 1e6 if api_us else None


class ReceiveToProducer:
    """The fed frames' receive times and producer times, to map the cycle meter's boundaries
    (receive times of frames) to those frames' producer times."""

    ENDS: Final = 8
    """Mapped boundaries remembered apart from the frames (a cycle's start is the previous
    cycle's end, which may be older than ``MAPPED_S``)."""

    def __init__(self) -> None:
        self.blocks: deque[tuple[FloatArray, FloatArray]] = deque()
        self.ends: OrderedDict[float, float] = OrderedDict()

    def add(self, received_s: FloatArray, producer_s: FloatArray) -> None:
        self.blocks.append((received_s, producer_s))
        newest_s = float(received_s[-1])
        while len(self.blocks) > 1 and float(self.blocks[0][0][-1]) < newest_s - MAPPED_S:
            self.blocks.popleft()

    def producer_s(self, received_s: float) -> float:
        """The producer time of the first frame received at ``received_s`` or later (the
        boundary's own frame); one older than every frame kept: ``received_s`` moved by the
        oldest kept frame's difference of clocks (a frame's lateness: the clocks of frames on
        time differ by nothing, ``producer_clock``)."""
        known = self.ends.get(received_s)
        if known is not None:
            return known
        for received, producer in self.blocks:
            if received_s <= received[-1]:
                index = int(np.searchsorted(received, received_s, side="left"))
                if index == 0 and received is self.blocks[0][0] and received_s < received[0]:
                    return received_s - float(received[0] - producer[0])
                mapped = float(producer[index])
                self.ends[received_s] = mapped
                while len(self.ends) > self.ENDS:
                    self.ends.popitem(last=False)
                return mapped
        return received_s  # not fed yet (never asked: a cycle waits for its end's frame)


class RobotHealth:
    """One robot's engine fed its frames and cycles (see the module docstring)."""

    name: Final = "health"
    runs: Final = Runs.THREAD

    def __init__(
        self,
        robot: RobotRuntime,
        engine: HealthEngine,
        queue_frames: int,
        api_s: Callable[[], float | None] | None = None,
    ) -> None:
        """``api_s``: the connection's T→O packet interval now (default: the robot's link's)."""
        self.robot = robot
        self.engine = engine
        self.queue_frames = queue_frames
        self.lock = threading.RLock()
        self.registration: Registration | None = None
        self.cycles: deque[tuple[float, float, bool]] = deque(maxlen=1000)
        """Measured cycles (start, end, interrupted) waiting for their frames."""
        self._times: list[float] = []
        self._payloads: list[bytes] = []
        """The frames' undecoded T→O payloads: read in place as one block
        (``FrameBlock.from_payloads``, a sixth of what the decoded frames cost)."""
        self._sequences: list[int] = []
        self.api_s = api_s if api_s is not None else lambda: granted_api_s(robot)
        self.clock = ProducerClock()
        self.mapped = ReceiveToProducer()
        self.received_until_s = -math.inf
        """The receive time of the last frame fed (the cycles' boundaries are receive times)."""
        self.frames_fed = 0
        self.cycles_fed = 0
        self.cycles_refused = 0
        """Cycles the engine could not take (no frames of theirs, out of order)."""

    # ------------------------------------------------------------ the health thread

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        """The queued frames (``Registration.deliver`` on the health thread)."""
        for record in records:
            self._times.append(record.received_at_s)
            self._sequences.append(record.t2o_sequence)
            self._payloads.append(record.raw)

    def step(self) -> None:
        """Take the queued frames, feed them, end the cycles whose frames are all in."""
        if self.registration is not None:
            self.registration.deliver()
        if self._payloads:
            received_s = np.asarray(self._times, dtype=np.float64)
            producer_s = self.clock.times(received_s, self._taken_sequences(), self.api_s())
            block = FrameBlock.from_payloads(producer_s, self._payloads)
            self._times, self._payloads = [], []
            self.mapped.add(received_s, producer_s)
            self.received_until_s = max(self.received_until_s, float(received_s[-1]))
            with self.lock:
                self.engine.observe(block)
            self.frames_fed += len(block)
        with self.lock:
            while self.cycles and self.cycles[0][1] <= self.received_until_s:
                start_s, end_s, interrupted = self.cycles.popleft()
                try:
                    self.engine.end_cycle(
                        self.mapped.producer_s(start_s), self.mapped.producer_s(end_s), interrupted
                    )
                    self.cycles_fed += 1
                except ValueError as error:
                    self.cycles_refused += 1
                    log.info("%s: health skipped a cycle: %s", self.robot.name, error)

    def _taken_sequences(self) -> IntArray | None:
        """The queued frames' T→O sequence numbers, emptied; None if one is not known."""
        sequences, self._sequences = self._sequences, []
        try:
            return np.asarray(sequences, dtype=np.int64)
        except (TypeError, ValueError):  # a None among them (a frame replayed without one)
            return None

    def adopt_arm(self, configured: str) -> None:
        """A fresh engine (no cycle, no baseline yet) takes the arm the robot's identity names
        once it is known (read after the connection came up)."""
        arm = arm_of(self.robot, configured)
        with self.lock:
            engine = self.engine
            fresh = engine.cycles == 0 and engine.baseline is None and engine.learning is None
            if arm is not engine.arm and fresh and not engine.history:
                self.engine = HealthEngine(arm, engine.settings)

    # ------------------------------------------------------------ any thread

    def add_cycle(self, start_s: float, end_s: float, interrupted: bool) -> None:
        if math.isfinite(start_s) and math.isfinite(end_s) and end_s > start_s:
            self.cycles.append((start_s, end_s, interrupted))

    def report(self, now_s: float) -> dict[str, object]:
        with self.lock:
            return self.engine.report(now_s)

    def document(self) -> tuple[dict[str, object], list[dict[str, object]]]:
        """The engine's document and every baseline's record (the one learning last)."""
        with self.lock:
            return self.engine.to_document(), self.baselines()[0]

    def begin_baseline(self, reason: str, by: str, now_s: float, cycles: int) -> dict[str, object]:
        with self.lock:
            return dict(self.engine.begin_baseline(reason, by, now_s, cycles=cycles))

    def baselines(self) -> tuple[list[dict[str, object]], object, object, int | None]:
        """Every baseline's record (the one learning last), the active one's id, the learning
        one's id and how many cycles it learned so far."""
        with self.lock:
            engine = self.engine
            records = [dict(info) for info in engine.history]
            learning = engine.learning
            if learning is not None:
                records.append(dict(learning.info))
            active = engine.baseline.info["id"] if engine.baseline is not None else None
            return (
                records,
                active,
                None if learning is None else learning.info["id"],
                None if learning is None else learning.cycles,
            )
