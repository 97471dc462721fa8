"""Layer: emulator, pure robot model (no I/O, no sockets, no asyncio). Imports the layout's
generated frames, the codec and the other ``robot`` modules; never the target or the scanner.

``SimulatedRobot`` is the robot behind the emulator's EtherNet/IP target: it implements the
target's ``ProcessImage`` protocol (``produce_frame``, ``consume_command``, ``outputs_idle``,
``command_image``) and offers the commands the control API exposes (stops, reset, buttons, forced
state, program, joints, inputs, tool offset, collaborative mode); its wear is ``wear``
(``robot.wear``: friction, heat, backlash, collisions, set through it). It is deterministic:
the same settings (seed included) and the same sequence of calls with the same times give the
same frames.
Every method takes the current time in seconds (any monotonic clock) and first brings the
simulation up to it.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Final

from cobot_hmi.codec import CommandImage
from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.emulator.robot.dynamics import (
    MotorThermal,
    joint_torques,
    motor_currents,
    worn_torques,
)
from cobot_hmi.emulator.robot.kinematics import (
    IDENTITY,
    Kinematics,
    Transform,
    euler_zyz_deg,
    forward,
    from_euler_zyz_deg,
    position_mm,
    tcp_velocity,
)
from cobot_hmi.emulator.robot.models import RobotModel, Vector3, model_by_name
from cobot_hmi.emulator.robot.noise import GaussianNoise
from cobot_hmi.emulator.robot.robot_io import RobotIO
from cobot_hmi.emulator.robot.states import (
    Flags,
    Phase,
    RobotCommandError,
    StateMachine,
    StateTimings,
)
from cobot_hmi.emulator.robot.trajectory import DEMO_STEPS, JointSample, ProgramRunner, at_rest
from cobot_hmi.emulator.robot.wear import Wear
from cobot_hmi.generated.frames import ControllerVersion, Frame, RobotState

CYCLE_MARKER_STEPS: Final = len(DEMO_STEPS) // 2
"""The cycle-start marker register is on while the program is in its first this many steps
(to the pick and back up: about a third of the cycle), so a late or lost frame never hides an
edge."""
KINEMATIC_REFRESH_MS_REAL: Final = 100.0
"""Doosan: monitoring values refresh about every 100 ms whatever the RPI (spec, reference facts)."""


@dataclass(slots=True)
class RobotSettings:
    """Everything that shapes the simulated robot; the defaults are the emulator's defaults."""

    model: str = "M1013"
    seed: int = 1
    timings: StateTimings = field(default_factory=StateTimings)
    autostart_program: bool = True
    collaborative: bool = False
    speed_fraction: float = 0.4
    """Fraction of each joint's speed limit the demo program uses."""
    accel_fraction: float = 0.5
    idle_behaviour: IdleBehaviour = IdleBehaviour.HOLD
    register_map: tuple[int | None, ...] | None = None
    """Bit output register n ← bit input register ``register_map[n]``; None = identity."""
    cycle_marker_register: int | None = None
    """The demo program sets this bit output register from the start of each cycle (the service's
    cycle trigger) through its first ``CYCLE_MARKER_STEPS`` steps; None = no marker
    (docs/emulator.md)."""
    kinematic_refresh_ms: float = 0.0
    """0: monitoring values are fresh in every frame; 100: as often as the real controller
    ("monitoring values refresh about every 100 ms, whatever the RPI": docs/emulator.md; the
    emulator verb's default)."""
    room_temperature_c: float = 25.0
    thermal_time_constant_s: float = 180.0
    temperature_rise_at_rated_current_c: float = 40.0
    payload_kg: float = 1.0
    tool_offset_position_mm: Vector3 = (0.0, 0.0, 0.0)
    tool_offset_orientation_deg: Vector3 = (0.0, 0.0, 0.0)
    controller_version: tuple[int, int, int] = (2, 12, 1)
    current_noise_a: float = 0.02
    external_torque_noise_nm: float = 0.15
    external_force_noise_n: float = 0.8
    external_moment_noise_nm: float = 0.08
    analog_input_noise: float = 0.005


def _tool_transform(position_mm: Sequence[float], orientation_deg: Sequence[float]) -> Transform:
    """The tool offset; exactly ``IDENTITY`` for none, which ``forward`` then skips."""
    tool = from_euler_zyz_deg(position_mm, orientation_deg)
    return IDENTITY if tool == IDENTITY else tool


Monitoring = tuple[tuple[float, ...], ...]
"""The joint and TCP values, refreshed together (every frame or every 100 ms): in the order
``produce_frame`` unpacks them into ``Frame`` fields of the same names. A plain tuple, not a
``Frame`` of its own: building a second frame per frame and copying fields out of it cost more
than the rest of ``produce_frame``."""


class _KinematicsCache:
    """The arm's kinematics and joint torques for the last motion sample, tool and payload: an
    arm at rest (a dwell, a stop, standby) needs them computed once, not every frame."""

    __slots__ = ("_last", "model")

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        self._last: tuple[JointSample, Transform, float, Kinematics, tuple[float, ...]] | None = (
            None
        )

    def at(
        self, motion: JointSample, tool: Transform, payload_kg: float
    ) -> tuple[Kinematics, tuple[float, ...]]:
        last = self._last
        if last is not None and last[1] is tool and last[2] == payload_kg and last[0] == motion:
            return last[3], last[4]
        position, velocity, acceleration = motion
        kin = forward(self.model, position, tool)
        torques = joint_torques(self.model, kin, velocity, acceleration, payload_kg)
        self._last = (motion, tool, payload_kg, kin, torques)
        return kin, torques


class _AnalogInputs:
    """The analog inputs with their noise: drawn each frame when monitoring values are, and
    with them when those refresh on a period (``kinematic_refresh_ms``), as the controller
    reports its monitoring data."""

    __slots__ = ("_at_s", "_io", "_noise", "_refresh_ms", "_values")

    def __init__(self, io: RobotIO, noise: GaussianNoise, refresh_ms: float) -> None:
        self._io, self._noise, self._refresh_ms = io, noise, refresh_ms
        self._values: tuple[float, ...] = ()
        self._at_s = -math.inf

    def now(self, monitoring_at_s: float) -> tuple[float, ...]:
        """The inputs now, their noise drawn again when the monitoring values were refreshed
        (at ``monitoring_at_s``)."""
        io = self._io
        if self._refresh_ms <= 0 or monitoring_at_s != self._at_s:
            self._values = self._noise.take(io.analog_input_count, io.analog_noise)
            self._at_s = monitoring_at_s
        return io.analog_input(self._values)


class _RefreshGrid:
    """The instants the monitoring values refresh at: whole periods from power-on, on the
    robot's own clock, as the controller's (every 100 ms whatever the RPI or the reader's
    timing), so a late read never moves the refreshes after it."""

    __slots__ = ("origin_s", "period_s")

    def __init__(self, period_s: float, origin_s: float) -> None:
        self.period_s, self.origin_s = period_s, origin_s

    def instant_s(self, at_s: float) -> float:
        """The grid's last instant at or before ``at_s`` (``-inf`` with no period)."""
        if self.period_s <= 0.0:
            return -math.inf
        # The epsilon: an instant read exactly on the grid is on it, whatever the rounding.
        periods = math.floor((at_s - self.origin_s) / self.period_s + 1e-9)
        return min(at_s, self.origin_s + periods * self.period_s)

    def next_s(self, at_s: float) -> float:
        """A hair before the grid's next instant after ``at_s`` (``instant_s`` may round onto
        it that early)."""
        return self.instant_s(at_s) + self.period_s * (1.0 - 1e-6)


def _cycle_marker(runner: ProgramRunner) -> bool:
    """The cycle-start marker: on through the first steps of each program cycle, rising as the
    cycle starts (it holds while the program pauses: no edge but a cycle's start)."""
    return runner.step_index < CYCLE_MARKER_STEPS


class SimulatedRobot:
    """A Doosan arm in a cell: motion, monitoring values, states, I/O. See the module docstring."""

    def __init__(self, settings: RobotSettings | None = None, start_s: float | None = None) -> None:
        """``start_s``: when the robot powers on; None = at the time of the first call."""
        self.settings = settings or RobotSettings()
        s = self.settings
        self.model = model_by_name(s.model)
        self._rng = random.Random(s.seed)
        self._noise = GaussianNoise(self._rng)
        self._states = StateMachine(
            start_s or 0.0,
            s.timings,
            autostart_program=s.autostart_program,
            collaborative=s.collaborative,
        )
        self._runner = ProgramRunner(self.model, DEMO_STEPS, s.speed_fraction, s.accel_fraction)
        self._io = RobotIO(
            s.idle_behaviour, s.register_map, s.analog_input_noise, s.cycle_marker_register
        )
        self._thermal = MotorThermal(
            self.model,
            s.room_temperature_c,
            s.thermal_time_constant_s,
            s.temperature_rise_at_rated_current_c,
        )
        self._tool = _tool_transform(s.tool_offset_position_mm, s.tool_offset_orientation_deg)
        self._controller_version = ControllerVersion(*s.controller_version)
        self._motion: JointSample = at_rest(self.model.demo_waypoints_deg[0])
        self._moving = False
        self._currents_a: tuple[float, ...] = (0.0,) * len(self.model.joints)
        self._started = start_s is not None
        self._now_s = start_s or 0.0
        self._refresh_grid = _RefreshGrid(s.kinematic_refresh_ms / 1000.0, self._now_s)
        self._monitoring: Monitoring | None = None
        self._kinematics = _KinematicsCache(self.model)
        self._monitoring_at_s = -math.inf
        self._frame: Frame | None = None
        self._frame_sent: Frame | None = None
        """The last frame produced, kept across changes: an equal new one is replaced by it."""
        self._analog = _AnalogInputs(self._io, self._noise, s.kinematic_refresh_ms)
        self._frame_at_s: float | None = None
        self._state_and_flags = self._states.state_and_flags()
        """Worked out at every ``_advance``: what the frame reports."""

        def wear_changed(now_s: float) -> None:
            """The wear is about to change: up to now without it, then fresh values with it."""
            self._command(now_s)
            self._monitoring = None

        self.wear = Wear(len(self.model.joints), wear_changed)
        """The robot's wear (``robot.wear``): set through it; the robot hears of each change."""

    # ------------------------------------------------------------------ simulation

    def _advance(self, now_s: float) -> None:
        """Up to ``now_s``. A monitoring refresh due on the way is made at its own instant of
        the grid, not at this call (the emulator's read of a robot that holds still comes when
        its loop wakes, late on a loaded host): the robot is first brought up to that instant."""
        if not self._started:
            self._started = True
            self._now_s = self._refresh_grid.origin_s = now_s
            self._states.restart(now_s)
        elif self._monitoring is not None and self._refresh_grid.period_s > 0.0:
            grid_s = self._refresh_grid.instant_s(now_s)
            if self._monitoring_at_s < grid_s < now_s and grid_s >= self._now_s:
                self._advance(grid_s)  # an instant of the grid: no refresh of its own before it
                self._monitoring = self._refresh_monitoring(self._state_and_flags[1])
                self._monitoring_at_s = grid_s
        states = self._states
        dt_s = now_s - self._now_s
        if dt_s <= 0.0:
            states.update(self._now_s)
            self._state_and_flags = states.state_and_flags()
            return
        states.update(now_s)
        state, flags = self._state_and_flags = states.state_and_flags()
        if states.motion_allowed(state):
            self._motion = self._runner.advance(self._motion.position, dt_s)
            self._moving = True
        else:
            self._stop_if_moving()
        if not flags.servo_on:
            self._currents_a = (0.0,) * len(self._currents_a)
        wear = self.wear
        extra_c = wear.extra_heat_c(now_s) if wear.active else None
        self._thermal.update(self._currents_a, dt_s, extra_c)
        self._now_s = now_s
        self._frame = None

    def _stop_if_moving(self) -> None:
        """Motion not allowed any more (a stop, a pause): hold where the arm is, at once, and
        plan the interrupted move again when the program resumes."""
        if self._moving or any(self._motion.velocity):
            self._runner.interrupt()
            self._motion = at_rest(self._motion.position)
            self._moving = False
            self._monitoring = None

    def _refresh_monitoring(self, flags: Flags) -> Monitoring:
        s = self.settings
        position, velocity, _ = self._motion
        kin, torques = self._kinematics.at(self._motion, self._tool, s.payload_kg)
        if self.wear.active:
            temperatures = self._thermal.temperatures_c
            torques = worn_torques(
                self.model,
                self.wear,
                torques,
                velocity,
                temperatures_c=temperatures,
                now_s=self._now_s,
            )
            position = self.wear.reported_positions(position, velocity, self._now_s)
        noise = self._noise.take
        joints = len(torques)
        if flags.servo_on:
            currents = motor_currents(self.model, torques, noise(joints, s.current_noise_a))
        else:
            currents = (0.0,) * joints  # brakes hold the arm; the drives carry no current
        self._currents_a = currents
        external_torque = noise(joints, s.external_torque_noise_nm)
        external_torque = self.wear.external_torques(external_torque, self._now_s)
        linear, angular = tcp_velocity(kin, velocity)
        # Noise drawn in this order (currents, external torque, force, moment): the seed's frames.
        return (
            position,
            velocity,
            currents,
            self._thermal.temperatures_c,
            torques,
            external_torque,
            position_mm(kin.tcp),
            euler_zyz_deg(kin.tcp),
            linear,
            angular,
            noise(3, s.external_force_noise_n),
            noise(3, s.external_moment_noise_nm),
        )

    def _monitoring_now(self, flags: Flags) -> Monitoring:
        """The monitoring values the frame carries: those of the last refresh (``_advance``
        makes it on the grid), or fresh ones now when an event dropped them (a stop, a wear
        change: shown at once) or every instant differs (no refresh period)."""
        if (
            self._monitoring is None
            or self.settings.kinematic_refresh_ms <= 0.0
            or self._refresh_grid.instant_s(self._now_s) > self._monitoring_at_s
        ):
            self._monitoring = self._refresh_monitoring(flags)
            self._monitoring_at_s = self._now_s
        return self._monitoring

    def frame_still_until_s(self) -> float:
        """Until when the last frame holds by itself (``process_image.HoldsStill``): the next
        monitoring refresh, a timed state transition (the end of INITIALIZING or SAFE_OFF,
        the program's autostart) or, while the program moves the arm, the end of its step (the
        part-present input and the cycle marker change only there), whichever comes first.
        Everything else in the frame changes only by a call (a command, the control API)."""
        now_s = self._now_s
        if self._refresh_grid.period_s <= 0.0 or self._frame is None or self._frame_at_s != now_s:
            return now_s
        until_s = self._refresh_grid.next_s(now_s)
        states = self._states
        if states.phase in (Phase.INITIALIZING, Phase.SAFE_OFF):
            until_s = min(until_s, states.phase_until_s)
        if states.autostart_at_s is not None:
            until_s = min(until_s, states.autostart_at_s)
        if states.motion_allowed(self._state_and_flags[0]):
            left_s = self._runner.step_left_s()
            if left_s is None:
                return now_s
            until_s = min(until_s, now_s + left_s)
        return max(now_s, until_s)

    # ------------------------------------------------------------------ ProcessImage

    @property
    def data_period_s(self) -> float:
        """The monitoring refresh period (0: fresh values at every instant)."""
        return self.settings.kinematic_refresh_ms / 1000.0

    def produce_frame(self, now_s: float) -> Frame:
        """The T→O frame to send now."""
        self._advance(now_s)
        if self._frame is not None and self._frame_at_s == self._now_s:
            return self._frame  # several connections producing at the same instant
        state, flags = self._state_and_flags
        (
            joint_position,
            joint_velocity,
            joint_motor_current,
            joint_motor_temperature,
            joint_torque,
            joint_external_torque,
            tcp_position,
            tcp_orientation,
            tcp_linear_velocity,
            tcp_angular_velocity,
            external_force,
            external_moment,
        ) = self._monitoring_now(flags)
        io = self._io
        applied = io.applied
        s = self.settings
        analog_input = self._analog.now(self._monitoring_at_s)
        # Positional, in the layout's field order (the comment names each field): a call with
        # thirty keywords costs about 2 µs more, and this runs for every produced frame. A test
        # (test_robot_motion) checks that values of the same shape stay in their own fields.
        frame = Frame(
            io.controlbox_di(self._runner.part_present),  # controlbox_di
            applied.controlbox_do,  # controlbox_do
            io.analog_input_type(),  # analog_input_type
            applied.analog_output_type,  # analog_output_type
            analog_input,  # analog_input
            applied.analog_output,  # analog_output
            io.tool_di(),  # tool_di
            applied.tool_do,  # tool_do
            self._controller_version,  # controller_version
            state,  # robot_state
            flags.servo_on,  # servo_on
            flags.safety_stopped,  # safety_stopped
            flags.emergency_stopped,  # emergency_stopped
            flags.direct_teach_button_pressed,  # direct_teach_button_pressed
            flags.power_button_pressed,  # power_button_pressed
            joint_position,  # joint_position
            joint_velocity,  # joint_velocity
            joint_motor_current,  # joint_motor_current
            joint_motor_temperature,  # joint_motor_temperature
            joint_torque,  # joint_torque
            joint_external_torque,  # joint_external_torque
            tcp_position,  # tcp_position
            tcp_orientation,  # tcp_orientation
            tcp_linear_velocity,  # tcp_velocity
            tcp_angular_velocity,  # tcp_angular_velocity
            s.tool_offset_position_mm,  # tool_offset_position
            s.tool_offset_orientation_deg,  # tool_offset_orientation
            external_force,  # external_force
            external_moment,  # external_moment
            io.bit_output_registers(_cycle_marker(self._runner)),  # bit_output_registers
        )
        previous = self._frame_sent
        if previous is not None and frame == previous:
            frame = previous  # nothing changed: the same object, so the target reuses its bytes
        self._frame = self._frame_sent = frame
        self._frame_at_s = self._now_s
        return frame

    def consume_command(self, image: CommandImage, now_s: float) -> None:
        """A connection owner in run (or an explicit Set_Attribute_Single) commands the outputs."""
        self._advance(now_s)
        self._io.consume_command(image)
        self._frame = None

    def outputs_idle(self, now_s: float) -> None:
        """The owner is idle, timed out or closed: apply the idle behaviour."""
        self._advance(now_s)
        self._io.outputs_idle()
        self._frame = None

    def command_image(self) -> CommandImage:
        """What the PLC last commanded."""
        return self._io.last_command

    # ------------------------------------------------------------------ commands

    def _command(self, now_s: float) -> None:
        self._advance(now_s)
        self._frame = None

    def _applied(self) -> None:
        """After a command changed the state: a stop or a pause takes effect at once."""
        if not self._states.motion_allowed():
            self._stop_if_moving()

    def estop(self, now_s: float) -> None:
        """Emergency stop: servo off and motion stopped at once."""
        self._command(now_s)
        self._states.emergency_stop()
        self._applied()

    def protective_stop(self, now_s: float) -> None:
        self._command(now_s)
        self._states.protective_stop()
        self._applied()

    def reset(self, now_s: float) -> None:
        """Clear a stop (or a forced state): SAFE_OFF, then standby."""
        self._command(now_s)
        self._states.reset(now_s)
        self._applied()

    def set_teach_button(self, pressed: bool, now_s: float) -> None:
        self._command(now_s)
        self._states.set_teach_button(pressed)
        self._applied()

    def set_power_button(self, pressed: bool, now_s: float) -> None:
        self._command(now_s)
        self._states.set_power_button(pressed)

    def set_collaborative(self, enabled: bool, now_s: float) -> None:
        self._command(now_s)
        self._states.set_collaborative(enabled)
        self._applied()

    def force_state(self, state: int, now_s: float) -> None:
        """Report ``state`` (any of the enum, or another byte value) until the next command."""
        self._command(now_s)
        self._states.force(state)
        self._applied()

    def set_program_running(self, running: bool, now_s: float) -> None:
        self._command(now_s)
        self._states.set_program_running(running)
        self._applied()

    def hold_joints(self, joints_deg: Sequence[float], now_s: float) -> None:
        """Stop the program and hold the arm at ``joints_deg`` (checked against the limits)."""
        if len(joints_deg) != len(self.model.joints):
            raise RobotCommandError(
                f"joint_position: expected {len(self.model.joints)} values, got {len(joints_deg)}"
            )
        for i, (value, spec) in enumerate(zip(joints_deg, self.model.joints, strict=True)):
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise RobotCommandError(f"joint_position[{i}]: expected a number, got {value!r}")
            if not math.isfinite(value) or abs(value) > spec.limit_deg:
                raise RobotCommandError(
                    f"joint_position[{i}]: {value} is outside J{i + 1}'s limits "
                    f"±{spec.limit_deg:g}°"
                )
        self._command(now_s)
        self._states.set_program_running(False)
        self._runner.interrupt()
        self._motion = at_rest(tuple(float(v) for v in joints_deg))
        self._moving = False
        self._monitoring = None

    def set_inputs(self, changes: Mapping[str, Mapping[object, object]], now_s: float) -> None:
        """Set DI 2–16, tool DI, AI and AI types from index maps (all or nothing)."""
        self._io.set_inputs(changes)
        self._command(now_s)

    def set_tool_offset(
        self, position_mm: Sequence[float], orientation_deg: Sequence[float], now_s: float
    ) -> None:
        values = [*position_mm, *orientation_deg]
        if len(position_mm) != 3 or len(orientation_deg) != 3:
            raise RobotCommandError("tool offset: expected 3 position and 3 angle values")
        if not all(isinstance(v, int | float) and math.isfinite(v) for v in values):
            raise RobotCommandError("tool offset: every value must be a finite number")
        self._command(now_s)
        position = (float(position_mm[0]), float(position_mm[1]), float(position_mm[2]))
        angles = (float(orientation_deg[0]), float(orientation_deg[1]), float(orientation_deg[2]))
        self.settings.tool_offset_position_mm = position
        self.settings.tool_offset_orientation_deg = angles
        self._tool = _tool_transform(position, angles)
        self._monitoring = None

    # ------------------------------------------------------------------ introspection

    def status(self) -> dict[str, object]:
        """The model's own view, beyond the frame (for the control API's ``GET /status``)."""
        machine = self._states
        state = machine.state()
        return {
            "model": self.model.name,
            "phase": machine.phase.value,
            "robot_state": state,
            "forced_state": state if machine.phase is Phase.FORCED else None,
            "program_running": machine.program_running,
            "collaborative": machine.collaborative,
            "teach_button_pressed": machine.teach_button_pressed,
            "power_button_pressed": machine.power_button_pressed,
            "program_step": self._runner.step_index,
            "program_cycles_completed": self._runner.cycles_completed,
            "part_present": self._runner.part_present,
            "outputs_owned_in_run": self._io.owner_in_run,
            "idle_behaviour": self._io.idle_behaviour.value,
            "kinematic_refresh_ms": self.settings.kinematic_refresh_ms,
        }


__all__ = [
    "RobotCommandError",
    "RobotSettings",
    "RobotState",
    "SimulatedRobot",
]
