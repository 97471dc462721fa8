"""Layer: emulator, pure robot model (no I/O). Imports only ``robot.models``.

Joint motion: synchronized point-to-point moves with a trapezoidal velocity profile, and the demo
program that strings them through the model's waypoints with dwells and a pause, forever.

Every move starts and ends at rest and runs every joint along a straight line in joint space on
one shared time profile ``q(t) = q0 + Δq·s(t)``, ``s`` going 0 → 1 with constant acceleration,
cruise, constant deceleration. The profile's peak rate and acceleration are the largest that keep
every joint inside its speed and acceleration limits (scaled by the program's fractions), so the
limits hold by construction; velocity and acceleration are the exact derivatives of position.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final, NamedTuple

from cobot_hmi.emulator.robot.models import RobotModel

_MIN_DELTA_DEG: Final = 1e-9
_MAX_STEPS_PER_ADVANCE: Final = 100_000
"""Bound on the steps one ``advance`` may walk through (each dwell lasts > 0, so it ends)."""


class JointSample(NamedTuple):
    """Joint positions (degree), velocities (degree/s) and accelerations (degree/s²)."""

    position: tuple[float, ...]
    velocity: tuple[float, ...]
    acceleration: tuple[float, ...]


def at_rest(position: Sequence[float]) -> JointSample:
    zeros = (0.0,) * len(position)
    return JointSample(tuple(position), zeros, zeros)


@dataclass(frozen=True, slots=True)
class JointMove:
    """A rest-to-rest move from ``start_deg`` by ``delta_deg`` on a trapezoidal profile."""

    start_deg: tuple[float, ...]
    delta_deg: tuple[float, ...]
    accel_s: float
    """Duration of the acceleration phase (and of the deceleration phase)."""
    duration_s: float
    peak_rate_per_s: float
    """Peak of ds/dt, where s runs from 0 to 1 over the move."""
    cruise: tuple[tuple[float, ...], tuple[float, ...]] = field(
        init=False, repr=False, compare=False
    )
    """Velocity and acceleration at the peak rate: the same for every sample of the cruise, so
    worked out once (with the very products ``sample`` would compute)."""

    def __post_init__(self) -> None:
        velocity = tuple([d * self.peak_rate_per_s for d in self.delta_deg])
        object.__setattr__(self, "cruise", (velocity, tuple([d * 0.0 for d in self.delta_deg])))

    @property
    def target_deg(self) -> tuple[float, ...]:
        return tuple(s + d for s, d in zip(self.start_deg, self.delta_deg, strict=True))

    def profile(self, t_s: float) -> tuple[float, float, float]:
        """``s``, ``ds/dt`` and ``d²s/dt²`` at ``t_s`` seconds into the move."""
        total, ta, peak = self.duration_s, self.accel_s, self.peak_rate_per_s
        if t_s <= 0.0 or total <= 0.0:
            return (0.0, 0.0, 0.0) if total > 0.0 else (1.0, 0.0, 0.0)
        if t_s >= total:
            return (1.0, 0.0, 0.0)
        accel = peak / ta
        if t_s < ta:
            return (0.5 * accel * t_s * t_s, accel * t_s, accel)
        if t_s <= total - ta:
            return (0.5 * accel * ta * ta + peak * (t_s - ta), peak, 0.0)
        left = total - t_s
        return (1.0 - 0.5 * accel * left * left, accel * left, -accel)

    def sample(self, t_s: float) -> JointSample:
        s, sd, sdd = self.profile(t_s)
        delta = self.delta_deg
        # tuple([...]) rather than tuple(generator): this runs for every produced frame.
        position = tuple([q0 + d * s for q0, d in zip(self.start_deg, delta, strict=True)])
        if sd == self.peak_rate_per_s and sdd == 0.0:
            # Cruising. ``profile`` never yields −0.0, so equal rates mean equal products.
            velocity, acceleration = self.cruise
            return JointSample(position, velocity, acceleration)
        return JointSample(
            position, tuple([d * sd for d in delta]), tuple([d * sdd for d in delta])
        )


def plan_move(
    start_deg: Sequence[float],
    target_deg: Sequence[float],
    max_speed_deg_s: Sequence[float],
    max_accel_deg_s2: Sequence[float],
) -> JointMove:
    """The fastest synchronized trapezoidal move within the given per-joint limits."""
    start = tuple(float(v) for v in start_deg)
    delta = tuple(float(t) - s for s, t in zip(start, target_deg, strict=True))
    rate = math.inf  # largest ds/dt every joint allows
    accel = math.inf  # largest d²s/dt² every joint allows
    for d, v_max, a_max in zip(delta, max_speed_deg_s, max_accel_deg_s2, strict=True):
        if abs(d) > _MIN_DELTA_DEG:
            rate = min(rate, v_max / abs(d))
            accel = min(accel, a_max / abs(d))
    if math.isinf(rate):
        return JointMove(start, delta, 0.0, 0.0, 0.0)
    if rate * rate / accel <= 1.0:  # reaches the peak rate: accelerate, cruise, decelerate
        accel_s = rate / accel
        return JointMove(start, delta, accel_s, 1.0 / rate + accel_s, rate)
    accel_s = math.sqrt(1.0 / accel)  # triangular: never reaches the peak rate
    return JointMove(start, delta, accel_s, 2.0 * accel_s, accel * accel_s)


@dataclass(frozen=True, slots=True)
class ProgramStep:
    """A move to a waypoint (``waypoint`` set) or a dwell (``dwell_s``) where the robot waits.

    ``part_present_after``: the value of the "part present" sensor (DI 1) once the step is done,
    or None to leave it.
    """

    waypoint: int | None = None
    dwell_s: float = 0.0
    part_present_after: bool | None = None


DEMO_STEPS: Final = (
    ProgramStep(waypoint=0),  # home
    ProgramStep(waypoint=1),  # above pick
    ProgramStep(waypoint=2),  # pick
    ProgramStep(dwell_s=0.4, part_present_after=True),  # gripper closes on the part
    ProgramStep(waypoint=1),
    ProgramStep(waypoint=3),  # transfer
    ProgramStep(waypoint=4),  # place
    ProgramStep(dwell_s=0.4, part_present_after=False),  # part released
    ProgramStep(waypoint=3),
    ProgramStep(waypoint=0),
    ProgramStep(dwell_s=1.5),  # pause at home, then the cycle repeats
)
"""The demo program: a pick-and-place cycle through the model's five waypoints."""


class ProgramRunner:
    """Walks the program's steps as time passes; pure, driven by ``advance``.

    A move is planned when its step starts, from wherever the robot then is, so the program can be
    interrupted (``interrupt``) and later resumed from any position without a jump: the current
    move is simply planned again from there.
    """

    def __init__(
        self,
        model: RobotModel,
        steps: Sequence[ProgramStep] = DEMO_STEPS,
        speed_fraction: float = 0.4,
        accel_fraction: float = 0.5,
    ) -> None:
        if not steps or not any(step.waypoint is None and step.dwell_s > 0 for step in steps):
            raise ValueError("a program needs at least one dwell with a positive duration")
        self.model = model
        self.steps = tuple(steps)
        self.max_speed_deg_s = tuple(j.max_speed_deg_s * speed_fraction for j in model.joints)
        self.max_accel_deg_s2 = tuple(j.max_accel_deg_s2 * accel_fraction for j in model.joints)
        self.step_index = 0
        self.step_elapsed_s = 0.0
        self.move: JointMove | None = None
        self.part_present = False
        self.cycles_completed = 0

    def interrupt(self) -> None:
        """Motion stopped mid-step: plan the current move again when the program resumes."""
        self.move = None
        if self.steps[self.step_index].waypoint is not None:
            self.step_elapsed_s = 0.0

    def step_left_s(self) -> float | None:
        """Running time left before the current step ends (and the next begins); None while
        the current move is not planned yet (``advance`` plans it from where the arm is)."""
        step = self.steps[self.step_index]
        if step.waypoint is None:
            return step.dwell_s - self.step_elapsed_s
        if self.move is None:
            return None
        return self.move.duration_s - self.step_elapsed_s

    def _step_duration(self, position: Sequence[float]) -> float:
        step = self.steps[self.step_index]
        if step.waypoint is None:
            return step.dwell_s
        if self.move is None:
            target = self.model.demo_waypoints_deg[step.waypoint]
            self.move = plan_move(position, target, self.max_speed_deg_s, self.max_accel_deg_s2)
        return self.move.duration_s

    def advance(self, position: Sequence[float], dt_s: float) -> JointSample:
        """Run the program for ``dt_s`` seconds from ``position`` (where the robot is now)."""
        remaining = max(0.0, dt_s)
        move = self.move
        if move is not None and self.step_elapsed_s + remaining < move.duration_s:
            # Still inside the planned move (most calls): the loop's first pass, without its
            # bookkeeping. A move is only ever planned for the current (waypoint) step.
            self.step_elapsed_s += remaining
            return move.sample(self.step_elapsed_s)
        current = tuple(position)
        for _ in range(_MAX_STEPS_PER_ADVANCE):
            duration = self._step_duration(current)
            if self.step_elapsed_s + remaining < duration:
                self.step_elapsed_s += remaining
                if self.move is not None:
                    return self.move.sample(self.step_elapsed_s)
                return at_rest(current)
            remaining -= duration - self.step_elapsed_s
            step = self.steps[self.step_index]
            if self.move is not None:
                current = self.move.target_deg
            if step.part_present_after is not None:
                self.part_present = step.part_present_after
            self.move = None
            self.step_elapsed_s = 0.0
            self.step_index = (self.step_index + 1) % len(self.steps)
            if self.step_index == 0:
                self.cycles_completed += 1
        return at_rest(current)
