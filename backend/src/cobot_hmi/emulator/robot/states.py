"""Layer: emulator, pure robot model (no I/O). Imports only the generated frames (RobotState).

The robot's state machine and the five status flags that follow it (issue 4):

- INITIALIZING at start (servo off) for ``initializing_s``, then STANDALONE_STANDBY with the
  servo on; STANDALONE_RUNNING while the program runs.
- Emergency stop: EMERGENCY_STOP, ``emergency_stopped`` set, servo off, motion stopped at once.
- Protective stop: INTERRUPTED with ``safety_stopped``; the servo stays on (a stop that holds
  position under servo control, as a protective stop of category 2 does), motion stopped.
- Reset (from either stop, or from a forced state): SAFE_OFF with the servo off for
  ``safe_off_s``, then standby with the servo on. The program does not restart by itself.
- Holding the direct-teach button in standby or while running: MANUAL_HANDGUIDING with
  ``direct_teach_button_pressed`` (the program pauses); releasing it returns to standby.
- Collaborative mode: the standby and running states become COLLABORATIVE_STANDBY / _RUNNING.
- Any of the 21 states can be forced; it then stays until the next command (reset, a stop, ...).

The two button flags report the buttons whatever the state. State numbers come from the
generated ``RobotState`` enum, never from literals.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Final, NamedTuple

from cobot_hmi.generated.frames import RobotState


class RobotCommandError(ValueError):
    """A command the robot refuses (a bad value, or the wrong state); nothing was changed."""


class RobotStateConflictError(RobotCommandError):
    """A well-formed command the robot refuses in its current state (reset first, ...)."""


class Phase(Enum):
    INITIALIZING = "initializing"
    NORMAL = "normal"
    EMERGENCY_STOP = "emergency_stop"
    PROTECTIVE_STOP = "protective_stop"
    SAFE_OFF = "safe_off"
    FORCED = "forced"


class Flags(NamedTuple):
    """The five status flags of T→O byte 34, in the table's order."""

    servo_on: bool
    safety_stopped: bool
    emergency_stopped: bool
    direct_teach_button_pressed: bool
    power_button_pressed: bool


MOTION_STATES: Final = frozenset(
    {
        RobotState.STANDALONE_RUNNING,
        RobotState.COLLABORATIVE_RUNNING,
        RobotState.HIGH_PRIORITY_RUNNING,
    }
)
"""States in which a running program moves the arm."""

_SERVO_OFF_STATES: Final = frozenset(
    {
        RobotState.EMERGENCY_STOP,
        RobotState.INITIALIZING,
        RobotState.SAFE_OFF,
        RobotState.BACKDRIVE_HOLD,
        RobotState.BACKDRIVE_RELEASE,
        RobotState.BACKDRIVE_RELEASE_BY_COCKPIT,
    }
)
"""States whose servo flag is off when forced (brakes engaged or drives disabled)."""


@dataclass(slots=True)
class StateTimings:
    initializing_s: float = 2.0
    """How long INITIALIZING lasts after start."""
    program_start_delay_s: float = 1.0
    """Standby time before the demo program starts by itself (when autostart is on)."""
    safe_off_s: float = 0.5
    """How long a reset stays in SAFE_OFF before standby."""


class StateMachine:
    """Phase, buttons and modes in; robot state and flags out. Time is passed in, in seconds."""

    def __init__(
        self,
        start_s: float,
        timings: StateTimings | None = None,
        *,
        autostart_program: bool = True,
        collaborative: bool = False,
    ) -> None:
        self.timings = timings or StateTimings()
        self.autostart_program = autostart_program
        self.phase = Phase.INITIALIZING
        self.phase_until_s = 0.0
        self.autostart_at_s: float | None = None
        self.restart(start_s)
        self.forced_state: int = RobotState.INITIALIZING
        self.teach_button_pressed = False
        self.power_button_pressed = False
        self.collaborative = collaborative
        self.program_running = False
        self._outputs_of: tuple[object, ...] = ()
        self._outputs: tuple[int, Flags] = (RobotState.INITIALIZING, Flags(*(False,) * 5))
        """``state_and_flags``'s last answer and the attributes it was worked out from."""

    # ------------------------------------------------------------------ time

    def restart(self, start_s: float) -> None:
        """Power on at ``start_s``: INITIALIZING, then standby, then (autostart) the program."""
        self.phase = Phase.INITIALIZING
        self.phase_until_s = start_s + self.timings.initializing_s
        self.autostart_at_s = (
            self.phase_until_s + self.timings.program_start_delay_s
            if self.autostart_program
            else None
        )

    def update(self, now_s: float) -> None:
        """Apply the timed transitions due by ``now_s``."""
        if self.phase in (Phase.INITIALIZING, Phase.SAFE_OFF) and now_s >= self.phase_until_s:
            self.phase = Phase.NORMAL
        if (
            self.autostart_at_s is not None
            and now_s >= self.autostart_at_s
            and self.phase is Phase.NORMAL
        ):
            self.autostart_at_s = None
            if not self.teach_button_pressed:
                self.program_running = True

    # ------------------------------------------------------------------ outputs

    def state(self) -> int:
        """The robot state (an int: a forced value outside the enum is reported as it is)."""
        match self.phase:
            case Phase.INITIALIZING:
                return RobotState.INITIALIZING
            case Phase.EMERGENCY_STOP:
                return RobotState.EMERGENCY_STOP
            case Phase.PROTECTIVE_STOP:
                return RobotState.INTERRUPTED
            case Phase.SAFE_OFF:
                return RobotState.SAFE_OFF
            case Phase.FORCED:
                return self.forced_state
        if self.teach_button_pressed:
            return RobotState.MANUAL_HANDGUIDING
        if self.collaborative:
            return (
                RobotState.COLLABORATIVE_RUNNING
                if self.program_running
                else RobotState.COLLABORATIVE_STANDBY
            )
        return (
            RobotState.STANDALONE_RUNNING if self.program_running else RobotState.STANDALONE_STANDBY
        )

    def flags(self) -> Flags:
        return self.state_and_flags()[1]

    def state_and_flags(self) -> tuple[int, Flags]:
        """``state()`` and ``flags()`` together (the state worked out once).

        Asked for every produced frame, and they change only with the attributes they are made
        of: the last answer is kept with those attributes and given again while they are equal.
        """
        inputs = (
            self.phase,
            self.forced_state,
            self.teach_button_pressed,
            self.power_button_pressed,
            self.collaborative,
            self.program_running,
        )
        if inputs == self._outputs_of:
            return self._outputs
        state = self.state()
        self._outputs_of = inputs
        self._outputs = (
            state,
            Flags(
                servo_on=state not in _SERVO_OFF_STATES,
                safety_stopped=state == RobotState.INTERRUPTED,
                emergency_stopped=state == RobotState.EMERGENCY_STOP,
                direct_teach_button_pressed=self.teach_button_pressed,
                power_button_pressed=self.power_button_pressed,
            ),
        )
        return self._outputs

    def motion_allowed(self, state: int | None = None) -> bool:
        """Whether the program moves the arm now (``state``: ``state()``, if already known)."""
        return self.program_running and (self.state() if state is None else state) in MOTION_STATES

    # ------------------------------------------------------------------ commands

    def emergency_stop(self) -> None:
        self.phase = Phase.EMERGENCY_STOP
        self.program_running = False
        self.autostart_at_s = None

    def protective_stop(self) -> None:
        if self.phase in (Phase.EMERGENCY_STOP, Phase.INITIALIZING, Phase.SAFE_OFF):
            raise RobotStateConflictError(
                f"no protective stop in {RobotState(self.state()).name}: the servo is off"
            )
        self.phase = Phase.PROTECTIVE_STOP
        self.program_running = False
        self.autostart_at_s = None

    def reset(self, now_s: float) -> None:
        if self.phase in (Phase.NORMAL, Phase.INITIALIZING):
            raise RobotStateConflictError(f"nothing to reset in {_state_name(self.state())}")
        self.phase = Phase.SAFE_OFF
        self.phase_until_s = now_s + self.timings.safe_off_s
        self.program_running = False

    def set_teach_button(self, pressed: bool) -> None:
        if pressed and not self.teach_button_pressed:
            self.program_running = False  # hand guiding pauses the program
        self.teach_button_pressed = pressed

    def set_power_button(self, pressed: bool) -> None:
        self.power_button_pressed = pressed

    def set_collaborative(self, enabled: bool) -> None:
        self.collaborative = enabled

    def set_program_running(self, running: bool) -> None:
        if running and self.phase is not Phase.FORCED:
            if self.phase is not Phase.NORMAL:
                raise RobotStateConflictError(
                    f"cannot start the program in {_state_name(self.state())}: reset first"
                )
            if self.teach_button_pressed:
                raise RobotStateConflictError(
                    "cannot start the program while the teach button is held"
                )
        self.program_running = running
        self.autostart_at_s = None

    def force(self, state: int) -> None:
        """Report ``state`` from now on, until the next command changes the phase."""
        if not 0 <= state <= 255:
            raise RobotCommandError(f"robot state {state} does not fit the USINT field (0–255)")
        self.phase = Phase.FORCED
        self.forced_state = state
        self.autostart_at_s = None
        if state not in MOTION_STATES:
            self.program_running = False


def _state_name(state: int) -> str:
    try:
        return RobotState(state).name
    except ValueError:
        return f"state {state}"
