"""Layer: service. One robot's health engine as a consumer of its frames and cycles, off the
cyclic path.

``RobotHealth`` is a frame consumer (``robots.frame_notifier``) that runs on the health
thread (``Runs.THREAD``): on the cyclic thread a frame costs one append into its bounded queue
(``health_queue_frames``; when health falls behind the oldest frames go and are counted in the
notifier's ``dropped``, ``/metrics``' ``cobot_hmi_consumer_dropped_frames_total``), never a
wait. The health thread takes the queued frames every ``health_refresh_s`` as one block (the
engine wants at least a second's frames a block) and feeds the engine; the cycle meter's cycles
(``cycle`` events, heard on the web loop) wait in ``cycles`` until the engine has seen every
frame of theirs, then end the cycle in the engine. Every call into the engine holds ``lock``:
the web loop asks for reports and baselines from a worker thread of its own.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from collections.abc import Sequence
from typing import Final

from cobot_hmi.arms import ARMS, Arm, arm_by_name
from cobot_hmi.health import FrameBlock, HealthEngine
from cobot_hmi.service.robots.frame_notifier import FrameRecord, Registration, Runs
from cobot_hmi.service.robots.robot import RobotRuntime

log = logging.getLogger(__name__)

VERDICT_RANK: Final = {"ok": 0, "watch": 1, "act": 2}


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


class RobotHealth:
    """One robot's engine fed its frames and cycles (see the module docstring)."""

    name: Final = "health"
    runs: Final = Runs.THREAD

    def __init__(self, robot: RobotRuntime, engine: HealthEngine, queue_frames: int) -> None:
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
        self.frames_fed = 0
        self.cycles_fed = 0
        self.cycles_refused = 0
        """Cycles the engine could not take (no frames of theirs, out of order)."""

    # ------------------------------------------------------------ the health thread

    def on_frames(self, robot: str, records: Sequence[FrameRecord]) -> None:
        """The queued frames (``Registration.deliver`` on the health thread)."""
        for record in records:
            self._times.append(record.received_at_s)
            self._payloads.append(record.raw)

    def step(self) -> None:
        """Take the queued frames, feed them, end the cycles whose frames are all in."""
        if self.registration is not None:
            self.registration.deliver()
        if self._payloads:
            block = FrameBlock.from_payloads(self._times, self._payloads)
            self._times, self._payloads = [], []
            with self.lock:
                self.engine.observe(block)
            self.frames_fed += len(block)
        with self.lock:
            last_s = self.engine.last_time_s
            while self.cycles and self.cycles[0][1] <= last_s:
                start_s, end_s, interrupted = self.cycles.popleft()
                try:
                    self.engine.end_cycle(start_s, end_s, interrupted)
                    self.cycles_fed += 1
                except ValueError as error:
                    self.cycles_refused += 1
                    log.info("%s: health skipped a cycle: %s", self.robot.name, error)

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
