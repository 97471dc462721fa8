"""Layer: emulator, pure robot model (no I/O). Imports ``robot.simulated`` and ``robot.wear``.

The simulated robot's program faster than real time, for the health engine's tests and
``cobot-hmi health simulate``: one cycle of the demo program is stepped once through
``SimulatedRobot`` without noise (its motion, joint torques, states), then every cycle is that
cycle again with what changes from cycle to cycle worked out in numpy: the wear's friction
(``Wear.friction_coefficients``, at the cycle's starting temperature), the motor temperatures
(``MotorThermal``'s first-order law solved exactly over the cycle's samples, with the wear's
extra heat) and the noise of currents and external torques. Thousands of cycles take seconds.
It is the same model as the emulator's frames, bar one simplification: a cycle's wear level and
cold friction are those at its start.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from cobot_hmi.emulator.robot.simulated import RobotSettings, SimulatedRobot
from cobot_hmi.emulator.robot.wear import Wear

Array = npt.NDArray[np.float64]
_MARKER_REGISTER = 0


class CycleFrames(NamedTuple):
    """One cycle's frames as arrays, the fields of ``health.FrameBlock`` by name."""

    time_s: Array
    position_deg: Array
    velocity_deg_s: Array
    torque_nm: Array
    current_a: Array
    external_torque_nm: Array
    temperature_c: Array
    robot_state: npt.NDArray[np.int64]
    servo_on: npt.NDArray[np.bool_]


class AcceleratedArm:
    """The program's cycle, recorded once at ``rate_hz``, repeated (see the module docstring)."""

    def __init__(self, settings: RobotSettings, rate_hz: float = 100.0) -> None:
        self.settings = settings
        quiet = dataclasses.replace(
            settings,
            current_noise_a=0.0,
            external_torque_noise_nm=0.0,
            cycle_marker_register=_MARKER_REGISTER,
            kinematic_refresh_ms=0.0,
        )
        robot = SimulatedRobot(quiet, start_s=0.0)
        self.model = robot.model
        step_s = 1.0 / rate_hz
        rows: list[tuple[object, ...]] = []
        starts = 0
        previous = False
        for k in range(int(120 * rate_hz)):
            frame = robot.produce_frame(k * step_s)
            marker = frame.bit_output_registers[_MARKER_REGISTER]
            if marker and not previous:
                starts += 1
                if starts == 3:
                    self.duration_s = k * step_s - float(rows[0][0])  # type: ignore[arg-type]
                    break
            previous = marker
            if starts == 2:
                rows.append((k * step_s, frame))
        else:
            raise RuntimeError("the program did not complete a cycle in 120 s")
        frames = [row[1] for row in rows]
        self.recorded_start_s = float(rows[0][0])  # type: ignore[arg-type]
        """When the recorded cycle started on the robot's clock (powered on at 0)."""
        self.offsets_s = np.array([row[0] for row in rows]) - float(rows[0][0])  # type: ignore[arg-type]
        self.position = np.array([f.joint_position for f in frames])  # type: ignore[attr-defined]
        self.velocity = np.array([f.joint_velocity for f in frames])  # type: ignore[attr-defined]
        self.torque = np.array([f.joint_torque for f in frames])  # type: ignore[attr-defined]
        self.state = np.array([f.robot_state for f in frames], dtype=np.int64)  # type: ignore[attr-defined]
        self.servo = np.array([f.servo_on for f in frames], dtype=np.bool_)  # type: ignore[attr-defined]
        self.step_s = step_s
        joints = self.model.joints
        self.torque_per_amp = np.array([j.torque_per_amp_nm for j in joints])
        self.viscous = np.array([j.viscous_friction_nm_s_deg for j in joints])
        self.rated_current = np.array([j.rated_current_a for j in joints])

    def cycle(
        self, start_s: float, temperatures_c: Array, wear: Wear, rng: np.random.Generator
    ) -> CycleFrames:
        """One cycle from ``start_s`` with the motors at ``temperatures_c`` at its start; the
        wear's clock is ``start_s``. The next cycle starts at ``start_s + duration_s``."""
        s = self.settings
        n, joints = self.torque.shape
        torque = self.torque
        if wear.active:
            coefficients = np.array(
                [
                    wear.friction_coefficients(
                        j, float(temperatures_c[j]), self.viscous[j], start_s
                    )
                    for j in range(joints)
                ]
            )
            torque = torque + coefficients[:, 0] * self.velocity
            torque = torque + coefficients[:, 1] * np.sign(self.velocity)
        current = torque / self.torque_per_amp + rng.normal(0.0, s.current_noise_a, (n, joints))
        extra = np.array(wear.extra_heat_c(start_s)) if wear.active else np.zeros(joints)
        target = (
            s.room_temperature_c
            + s.temperature_rise_at_rated_current_c * (current / self.rated_current) ** 2
            + extra
        )
        keep = math.exp(-self.step_s / s.thermal_time_constant_s)
        powers = keep ** np.arange(n + 1, dtype=np.float64)
        # T_k = keep^k·(T_0 + (1 − keep)·Σ_{i<k} target_i·keep^−(i+1)): the recurrence, exactly.
        weighted = np.cumsum(target / powers[1:, None], axis=0)
        weighted = np.vstack([np.zeros(joints), weighted[:-1]])
        temperature = powers[:n, None] * (temperatures_c + (1.0 - keep) * weighted)
        external = rng.normal(0.0, s.external_torque_noise_nm, (n, joints))
        return CycleFrames(
            start_s + self.offsets_s,
            self.position,
            self.velocity,
            torque,
            current,
            external,
            temperature,
            self.state,
            self.servo,
        )

    def end_temperatures(self, frames: CycleFrames) -> Array:
        """The motors' temperatures one step after the cycle's last frame."""
        s = self.settings
        last = frames.current_a[-1]
        target = (
            s.room_temperature_c
            + s.temperature_rise_at_rated_current_c * (last / self.rated_current) ** 2
        )
        keep = math.exp(-self.step_s / s.thermal_time_constant_s)
        return np.asarray(target + (frames.temperature_c[-1] - target) * keep)
