"""Layer: emulator, pure robot model (no I/O). Imports nothing of the project.

The emulated robot's wear (issue 40, docs/emulator.md "Wear"): per joint, friction added
(``friction_percent`` of the joint's healthy viscous friction, or Coulomb and viscous terms of
its own), friction that is higher cold and settles as the motor warms, a motor that runs hot
for its duty, and backlash; each reaching its full size over ``ramp_s`` of wear time. Wear time
runs ``time_factor`` times faster than the robot's clock, so days of wear fit in minutes for
tests and demos. A collision (``Wear.collide``) is an event rather than wear: an external-torque
spike on one joint for a moment, which the control API pairs with the protective stop the
controller answers it with.

The robot that owns a ``Wear`` hears of every change before it is made (``changed``), so it
first brings its simulation up to that instant: wear never reaches back into the past.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from typing import Final

COLD_C: Final = 25.0
"""``cold_friction_percent`` is the extra friction at or below this motor temperature ..."""
WARM_C: Final = 45.0
"""... fading linearly to none at this one."""
MAX_PERCENT: Final = 1000.0
MAX_RAMP_S: Final = 365 * 86_400.0
MAX_TIME_FACTOR: Final = 1_000_000.0
MAX_MOTOR_TEMPERATURE_RISE_C: Final = 200.0
"""The most a scenario (or ``--motor-temperature-rise-c``) may say a motor settles above room
temperature at its rated current."""
COLLISION_S: Final = 0.2
"""How long a collision's external-torque spike shows in the frames."""


class WearError(ValueError):
    """A wear entry that cannot be applied; ``field`` names the bad value."""

    def __init__(self, reason: str, field: str | None = None) -> None:
        super().__init__(reason)
        self.field = field


@dataclass(frozen=True, slots=True)
class JointWear:
    friction_percent: float = 0.0
    """Extra friction, in % of the joint's healthy friction at its temperature."""
    coulomb_nm: float = 0.0
    viscous_nm_s_deg: float = 0.0
    cold_friction_percent: float = 0.0
    hot_c: float = 0.0
    """The motor settles this many °C above what its current explains."""
    backlash_deg: float = 0.0
    """Lost motion: the reported position trails the motion by half of it."""
    ramp_s: float = 0.0
    """Wear seconds to reach full size (0: at once)."""


_LIMITS: Final = {
    "friction_percent": (-90.0, MAX_PERCENT),
    "coulomb_nm": (0.0, 500.0),
    "viscous_nm_s_deg": (0.0, 10.0),
    "cold_friction_percent": (0.0, MAX_PERCENT),
    "hot_c": (0.0, 100.0),
    "backlash_deg": (0.0, 5.0),
    "ramp_s": (0.0, MAX_RAMP_S),
}


def parse_entry(data: Mapping[str, object], joints: int) -> tuple[int, JointWear]:
    """``{"joint": 3, "friction_percent": 25, ...}`` (joints 1–N as the robot labels them) →
    (joint index from 0, its wear); ``ramp_h`` is accepted for ``ramp_s``/3600."""
    allowed = ("joint", "ramp_h", *_LIMITS)
    for name in data:
        if name not in allowed:
            raise WearError(f"unknown field {name!r}; expected {', '.join(allowed)}", name)
    joint = data.get("joint")
    if isinstance(joint, bool) or not isinstance(joint, int) or not 1 <= joint <= joints:
        raise WearError(f"joint: expected an integer 1–{joints}, got {joint!r}", "joint")
    values: dict[str, float] = {}
    for name, value in data.items():
        if name == "joint":
            continue
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise WearError(f"{name}: expected a finite number, got {value!r}", name)
        key, number = (
            ("ramp_s", float(value) * 3600.0) if name == "ramp_h" else (name, float(value))
        )
        low, high = _LIMITS[key]
        if not low <= number <= high:
            raise WearError(f"{name}: {value} is outside {low:g}–{high:g}", name)
        values[key] = number
    return joint - 1, JointWear(**values)


class Wear:
    """Each joint's wear, applied at a time of the robot's clock, and the wear clock's factor."""

    def __init__(self, joints: int, changed: Callable[[float], None] | None = None) -> None:
        self.joints: list[JointWear] = [JointWear()] * joints
        self.applied_at_s: list[float] = [0.0] * joints
        """On the wear clock (``wear_clock_s``)."""
        self.time_factor = 1.0
        self._clock_at_s = 0.0
        self._clock_base_s = 0.0
        self.active = False
        self._changed = changed
        self._collision: tuple[int, float, float] | None = None
        """A collision's joint, external torque (N·m) and end time."""

    def _change(self, now_s: float) -> None:
        if self._changed is not None:
            self._changed(now_s)

    def set(self, joint: int, wear: JointWear, now_s: float) -> None:
        self._change(now_s)
        self.joints[joint] = wear
        self.applied_at_s[joint] = self.wear_clock_s(now_s)
        self.active = any(w != JointWear() for w in self.joints)

    def set_time_factor(self, factor: float, now_s: float) -> None:
        if not 1.0 <= factor <= MAX_TIME_FACTOR:
            raise WearError(
                f"time_factor: {factor} is outside 1–{MAX_TIME_FACTOR:g}", "time_factor"
            )
        self._change(now_s)
        self._clock_base_s = self.wear_clock_s(now_s)
        self._clock_at_s = now_s
        self.time_factor = factor

    def wear_clock_s(self, now_s: float) -> float:
        """The wear clock: ``time_factor`` seconds for each of the robot's since it was set."""
        return self._clock_base_s + (now_s - self._clock_at_s) * self.time_factor

    def clear(self, now_s: float) -> None:
        """No wear on any joint (the time factor stays)."""
        self._change(now_s)
        self.joints = [JointWear()] * len(self.joints)
        self.active = False

    def collide(self, joint: int, external_torque_nm: float, now_s: float) -> None:
        self._change(now_s)
        self._collision = (joint, external_torque_nm, now_s + COLLISION_S)

    def external_torques(self, noise_nm: tuple[float, ...], now_s: float) -> tuple[float, ...]:
        """The external torques with a collision's spike while it lasts."""
        collision = self._collision
        if collision is None:
            return noise_nm
        joint, torque_nm, until_s = collision
        if now_s >= until_s:
            self._collision = None
            return noise_nm
        spiked = list(noise_nm)
        spiked[joint] += torque_nm
        return tuple(spiked)

    def level(self, joint: int, now_s: float) -> float:
        """How far the joint's wear has grown (0–1)."""
        ramp_s = self.joints[joint].ramp_s
        if ramp_s <= 0.0:
            return 1.0
        grown_s = self.wear_clock_s(now_s) - self.applied_at_s[joint]
        return min(1.0, max(0.0, grown_s / ramp_s))

    def friction_coefficients(
        self, joint: int, temperature_c: float, healthy_viscous_nm_s_deg: float, now_s: float
    ) -> tuple[float, float]:
        """The viscous (N·m per °/s) and Coulomb (N·m) friction the wear adds to the joint."""
        wear = self.joints[joint]
        level = self.level(joint, now_s)
        cold = min(1.0, max(0.0, (WARM_C - temperature_c) / (WARM_C - COLD_C)))
        # friction_percent is of the healthy friction at this temperature, the cold part with it.
        cold_factor = 1.0 + wear.cold_friction_percent * cold / 100.0
        percent = (cold_factor - 1.0) * 100.0 + cold_factor * wear.friction_percent * level
        viscous = healthy_viscous_nm_s_deg * percent / 100.0 + wear.viscous_nm_s_deg * level
        return viscous, wear.coulomb_nm * level

    def friction_nm(
        self,
        joint: int,
        velocity_deg_s: float,
        temperature_c: float,
        healthy_viscous_nm_s_deg: float,
        now_s: float,
    ) -> float:
        """The friction torque the wear adds to the joint's healthy friction."""
        viscous, coulomb = self.friction_coefficients(
            joint, temperature_c, healthy_viscous_nm_s_deg, now_s
        )
        sign = 1.0 if velocity_deg_s > 0.0 else -1.0 if velocity_deg_s < 0.0 else 0.0
        return viscous * velocity_deg_s + sign * coulomb

    def extra_heat_c(self, now_s: float) -> tuple[float, ...]:
        return tuple(w.hot_c * self.level(j, now_s) for j, w in enumerate(self.joints))

    def reported_positions(
        self, position_deg: Sequence[float], velocity_deg_s: Sequence[float], now_s: float
    ) -> tuple[float, ...]:
        """Positions as the arm's link is, trailing the motion by half the backlash."""
        return tuple(
            q - math.copysign(w.backlash_deg * self.level(j, now_s) / 2.0, v) if v else q
            for j, (q, v, w) in enumerate(
                zip(position_deg, velocity_deg_s, self.joints, strict=True)
            )
        )

    def view(self, now_s: float) -> dict[str, object]:
        """The control API's answer: each worn joint's wear and how far it has grown (0–1)."""
        return {
            "time_factor": self.time_factor,
            "joints": [
                {"joint": j + 1, **asdict(w), "level": round(self.level(j, now_s), 6)}
                for j, w in enumerate(self.joints)
                if w != JointWear()
            ],
        }


@dataclass(frozen=True, slots=True)
class WearScenario:
    """A wear scenario file (``cobot-hmi emulator --wear FILE``, docs/emulator.md "Wear"):
    ``{"time_factor": 1000, "wear": [{"joint": 3, "friction_percent": 25, "ramp_h": 168}]}``.
    ``motor_temperature_rise_c`` shapes the robot rather than its wear (the motors' rise above
    room temperature at rated current, ``RobotSettings.temperature_rise_at_rated_current_c``):
    the emulator reads it before it builds the robot; ``apply`` leaves it alone."""

    time_factor: float
    entries: tuple[tuple[int, JointWear], ...]
    motor_temperature_rise_c: float | None = None

    def apply(self, wear: Wear, now_s: float) -> None:
        wear.set_time_factor(self.time_factor, now_s)
        for joint, entry in self.entries:
            wear.set(joint, entry, now_s)


def parse_scenario(data: object, joints: int) -> WearScenario:
    """A scenario from its JSON (``WearError`` naming what is wrong, nothing applied)."""
    if not isinstance(data, dict):
        raise WearError(f"expected a JSON object, got {type(data).__name__}")
    known = {"time_factor", "wear", "motor_temperature_rise_c"}
    unknown = sorted(set(data) - known)
    if unknown:
        expected = ", ".join(sorted(known))
        raise WearError(f"unknown field {unknown[0]!r}; expected {expected}", unknown[0])
    factor = data.get("time_factor", 1.0)
    if isinstance(factor, bool) or not isinstance(factor, int | float):
        raise WearError(f"time_factor: expected a number, got {factor!r}", "time_factor")
    if not 1.0 <= factor <= MAX_TIME_FACTOR:
        raise WearError(f"time_factor: {factor} is outside 1–{MAX_TIME_FACTOR:g}", "time_factor")
    entries = data.get("wear", [])
    if not isinstance(entries, list):
        raise WearError("wear: expected a list of joint entries", "wear")
    parsed = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise WearError(f"wear[{i}]: expected an object", "wear")
        try:
            parsed.append(parse_entry(entry, joints))
        except WearError as error:
            raise WearError(f"wear[{i}]: {error}", error.field) from None
    return WearScenario(float(factor), tuple(parsed), _temperature_rise_c(data))


def _temperature_rise_c(data: Mapping[str, object]) -> float | None:
    rise = data.get("motor_temperature_rise_c")
    if rise is None:
        return None
    name = "motor_temperature_rise_c"
    if isinstance(rise, bool) or not isinstance(rise, int | float):
        raise WearError(f"{name}: expected a number of °C, got {rise!r}", name)
    if not 0.0 <= rise <= MAX_MOTOR_TEMPERATURE_RISE_C:
        raise WearError(f"{name}: {rise} is outside 0–{MAX_MOTOR_TEMPERATURE_RISE_C:g}", name)
    return float(rise)


WEAR_FIELDS: Final = tuple(f.name for f in fields(JointWear))
