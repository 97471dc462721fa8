"""Layer: health (pure). Imports ``health.frames`` and the layout's state table.

Knocks: external-torque peaks over a threshold (a fraction of the joint's rated torque), the
protective and emergency stops and the servo-offs, counted per shift, each with where in joint
space it happened. An event is an edge (over the threshold, into the stop state, servo on to
off), so a stop that lasts is counted once.
"""

from __future__ import annotations

from typing import Final

import numpy as np

from cobot_hmi.health.frames import BoolArray, FloatArray, FrameBlock
from cobot_hmi.layout import ROBOT_STATES

_STATE: Final = {state.name: state.value for state in ROBOT_STATES}
PROTECTIVE_STOP: Final = _STATE["INTERRUPTED"]
EMERGENCY_STOP: Final = _STATE["EMERGENCY_STOP"]
MAX_EVENTS: Final = 100
KINDS: Final = ("collision", "protective_stop", "emergency_stop", "servo_off")


def _rising(now: BoolArray, before: BoolArray) -> BoolArray:
    previous = np.concatenate([before[None, ...], now[:-1]], axis=0)
    rising: BoolArray = now & ~previous
    return rising


class KnockCounter:
    """This shift's counts and the latest events (see the module docstring)."""

    def __init__(self, threshold_nm: FloatArray, shift_hours: float, shift_origin_s: float) -> None:
        self.threshold_nm = threshold_nm
        self.shift_s = shift_hours * 3600.0
        self.shift_origin_s = shift_origin_s
        joints = threshold_nm.size
        self.shift_start_s: float | None = None
        self.collisions = [0] * joints
        self.counts = dict.fromkeys(KINDS[1:], 0)
        self.events: list[dict[str, object]] = []
        self._over: BoolArray = np.zeros(joints, dtype=np.bool_)
        self._stopped = np.zeros(2, dtype=np.bool_)
        self._servo_on = True

    def _shift_of(self, time_s: float) -> float:
        index = (time_s - self.shift_origin_s) // self.shift_s
        return self.shift_origin_s + index * self.shift_s

    def add(self, block: FrameBlock) -> None:
        if len(block) == 0:
            return
        shift = self._shift_of(float(block.time_s[-1]))
        if shift != self.shift_start_s:
            self.shift_start_s = shift
            self.collisions = [0] * len(self.collisions)
            self.counts = dict.fromkeys(KINDS[1:], 0)
        # Each edge search only where there can be an edge (nothing over, no stop, the servo
        # on, in the block and before it: the usual second has none).
        over = np.abs(block.external_torque_nm) > self.threshold_nm
        if over.any():
            for i, j in zip(*np.nonzero(_rising(over, self._over)), strict=True):
                self.collisions[int(j)] += 1
                peak = float(block.external_torque_nm[i, j])
                self._event(block, int(i), "collision", int(j) + 1, peak)
        self._over = over[-1]
        stops = np.stack(
            [block.robot_state == PROTECTIVE_STOP, block.robot_state == EMERGENCY_STOP], axis=1
        )
        if stops.any():
            for i, k in zip(*np.nonzero(_rising(stops, self._stopped)), strict=True):
                kind = KINDS[1 + int(k)]
                self.counts[kind] += 1
                self._event(block, int(i), kind, None, None)
        self._stopped = stops[-1]
        if not block.servo_on.all():
            servo_off = ~block.servo_on
            for i in np.nonzero(_rising(servo_off, np.array(not self._servo_on)))[0]:
                self.counts["servo_off"] += 1
                self._event(block, int(i), "servo_off", None, None)
        self._servo_on = bool(block.servo_on[-1])

    def _event(
        self, block: FrameBlock, i: int, kind: str, joint: int | None, peak_nm: float | None
    ) -> None:
        self.events.append(
            {
                "time": float(block.time_s[i]),
                "kind": kind,
                "joint": joint,
                "external_torque_nm": peak_nm,
                "joint_position_deg": [round(float(q), 2) for q in block.position_deg[i]],
            }
        )
        del self.events[:-MAX_EVENTS]

    def to_state(self) -> dict[str, object]:
        return {
            "shift_start_s": self.shift_start_s,
            "collisions": self.collisions,
            "counts": self.counts,
            "events": self.events,
            "over": self._over.tolist(),
            "stopped": self._stopped.tolist(),
            "servo_on": self._servo_on,
        }

    def restore(self, state: dict[str, object]) -> None:
        start = state["shift_start_s"]
        self.shift_start_s = None if start is None else float(start)  # type: ignore[arg-type]
        self.collisions = [int(c) for c in state["collisions"]]  # type: ignore[attr-defined]
        self.counts = {str(k): int(v) for k, v in state["counts"].items()}  # type: ignore[attr-defined]
        self.events = list(state["events"])  # type: ignore[call-overload]
        self._over = np.array(state["over"], dtype=np.bool_)
        self._stopped = np.array(state["stopped"], dtype=np.bool_)
        self._servo_on = bool(state["servo_on"])
