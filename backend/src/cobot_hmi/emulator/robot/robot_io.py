"""Layer: emulator, pure robot model (no I/O). Imports the layout, the codec, ``robot.states`` and
the target's ``process_image`` interface types (pure).

The robot's I/O as the controller sees it:

- Outputs (ControlBox DO, tool DO, AO and AO types): follow the PLC's command while a connection
  in run owns them; when the owner goes idle, times out or closes, the idle behaviour applies
  (``hold`` the last values, or ``clear`` them to the all-zero image).
- Bit output registers: the robot program copies bit input register ``register_map[n]`` to bit
  output register ``n`` (identity by default; ``None`` leaves the output off); the demo program's
  cycle-start marker, when set, takes its register instead.
- Inputs: DI 1 is the program's "part present" sensor; the other ControlBox DI, the tool DI, the
  analog inputs (a little noise added on every frame) and their types are set from outside.

Names and counts come from the layout (``field_by_name``), never typed again here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Final

from cobot_hmi.codec import CommandImage, zero_command
from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.emulator.robot.states import RobotCommandError
from cobot_hmi.layout import Direction, Field, field_by_name

PART_PRESENT_DI_INDEX: Final = 0
"""DI 1 (index 0) follows the program: the "part present" sensor."""

SETTABLE_INPUTS: Final = ("controlbox_di", "tool_di", "analog_input", "analog_input_type")
"""T→O inputs that can be set from outside (issue 4)."""

_BIT_INPUT_REGISTERS: Final = field_by_name(Direction.O_TO_T, "bit_input_registers")
_BIT_OUTPUT_REGISTERS: Final = field_by_name(Direction.T_TO_O, "bit_output_registers")


def identity_register_map() -> tuple[int | None, ...]:
    """Bit output register n ← bit input register n, for every register."""
    return tuple(range(_BIT_OUTPUT_REGISTERS.count))


def validate_register_map(register_map: Sequence[int | None]) -> tuple[int | None, ...]:
    if len(register_map) != _BIT_OUTPUT_REGISTERS.count:
        raise ValueError(
            f"register map: expected {_BIT_OUTPUT_REGISTERS.count} entries, got {len(register_map)}"
        )
    for n, source in enumerate(register_map):
        if source is not None and not 0 <= source < _BIT_INPUT_REGISTERS.count:
            raise ValueError(f"register map [{n}]: no bit input register {source}")
    return tuple(register_map)


def output_register(text: str) -> int:
    """A bit output register's number from text; ``ValueError`` naming the range otherwise."""
    count = _BIT_OUTPUT_REGISTERS.count
    if not text.strip().isdigit() or int(text) >= count:
        raise ValueError(f"no bit output register {text!r}: they are 0–{count - 1}")
    return int(text)


def parse_register_map(text: str) -> tuple[int | None, ...]:
    """A register map from ``"OUT=IN,OUT=-"`` changes to the identity (``-``: always off).

    ``"0=1,1=0,63=-"`` swaps registers 0 and 1 and switches output register 63 off; ``ValueError``
    with a reason for anything else.
    """
    mapping: list[int | None] = list(identity_register_map())
    for item in filter(None, (part.strip() for part in text.split(","))):
        out_text, sep, in_text = item.partition("=")
        if not sep or not out_text.strip().isdigit():
            raise ValueError(f"register map: {item!r} is not OUT=IN or OUT=-")
        out = int(out_text)
        if out >= len(mapping):
            raise ValueError(f"register map: no bit output register {out}")
        source = in_text.strip()
        if source == "-":
            mapping[out] = None
        elif source.isdigit():
            mapping[out] = int(source)
        else:
            raise ValueError(f"register map: {item!r} is not OUT=IN or OUT=-")
    return validate_register_map(mapping)


def _checked_value(f: Field, where: str, value: object) -> bool | int | float:
    kind = f.value_kind
    if kind == "bool":
        if isinstance(value, bool):
            return value
        raise RobotCommandError(f"{where}: expected true or false, got {value!r}")
    if kind == "int":
        if (
            isinstance(value, bool)
            or not isinstance(value, int)
            or not 0 <= value < len(f.value_names)
        ):
            raise RobotCommandError(
                f"{where}: expected 0 to {len(f.value_names) - 1} "
                f"({', '.join(f.value_names)}), got {value!r}"
            )
        return value
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise RobotCommandError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _zeros(f: Field) -> list[bool | int | float]:
    zero: bool | int | float = {"bool": False, "int": 0}.get(f.value_kind, 0.0)
    return [zero] * f.count


class RobotIO:
    """Inputs, outputs and registers; mutated only through its methods."""

    def __init__(
        self,
        idle_behaviour: IdleBehaviour = IdleBehaviour.HOLD,
        register_map: Sequence[int | None] | None = None,
        analog_noise: float = 0.005,
        cycle_marker_register: int | None = None,
    ) -> None:
        if cycle_marker_register is not None and not (
            0 <= cycle_marker_register < _BIT_OUTPUT_REGISTERS.count
        ):
            raise ValueError(f"cycle marker: no bit output register {cycle_marker_register}")
        self.cycle_marker_register = cycle_marker_register
        """The program's cycle-start marker, in place of the copied input register."""
        self.idle_behaviour = idle_behaviour
        self.register_map = validate_register_map(register_map or identity_register_map())
        self.analog_noise = analog_noise
        self.last_command: CommandImage = zero_command()
        """What the PLC last commanded (kept through idle, as the O→T assembly data is)."""
        self.applied: CommandImage = zero_command()
        """What the outputs and input registers actually are."""
        self.inputs: dict[str, list[bool | int | float]] = {
            name: _zeros(field_by_name(Direction.T_TO_O, name)) for name in SETTABLE_INPUTS
        }
        self.owner_in_run = False
        # Frame parts built once and kept until what they come from changes (not per frame).
        self._controlbox_di: dict[bool, tuple[bool, ...]] = {}
        self._tool_di: tuple[bool, ...] | None = None
        self._analog_input_type: tuple[int, ...] | None = None
        self._analog_input: tuple[float, ...] | None = None
        self._registers_of: CommandImage | None = None
        self._registers: tuple[bool, ...] = ()
        self._marked: dict[bool, tuple[bool, ...]] = {}

    def consume_command(self, image: CommandImage) -> None:
        """A connection owner in run (or an explicit write) commands the outputs."""
        self.last_command = image
        self.applied = image
        self.owner_in_run = True

    def outputs_idle(self) -> None:
        """No owner in run any more: apply the idle behaviour."""
        self.owner_in_run = False
        if self.idle_behaviour is IdleBehaviour.CLEAR:
            self.applied = zero_command()

    def set_inputs(self, changes: Mapping[str, Mapping[object, object]]) -> None:
        """Set inputs from ``{"field": {"index": value}}`` maps; all or nothing.

        ``RobotCommandError`` (nothing changed) for an unknown or unsettable field, a bad index,
        DI 1 (it follows the program) or a value of the wrong kind.
        """
        staged: list[tuple[str, int, bool | int | float]] = []
        if not isinstance(changes, Mapping):
            raise RobotCommandError("inputs: expected an object of index maps")
        for name, values in changes.items():
            if name not in SETTABLE_INPUTS:
                raise RobotCommandError(
                    f"{name!r} cannot be set; settable inputs: {', '.join(SETTABLE_INPUTS)}"
                )
            f = field_by_name(Direction.T_TO_O, name)
            if not isinstance(values, Mapping):
                raise RobotCommandError(f"{name}: expected a map from index to value")
            for key, value in values.items():
                text = str(key)
                if not text.isdigit() or int(text) >= f.count:
                    raise RobotCommandError(f"{name}: index {key!r} out of range 0–{f.count - 1}")
                index = int(text)
                if name == "controlbox_di" and index == PART_PRESENT_DI_INDEX:
                    raise RobotCommandError(
                        "controlbox_di[0] (DI 1) follows the program (part present)"
                    )
                staged.append((name, index, _checked_value(f, f"{name}[{index}]", value)))
        for name, index, value in staged:
            self.inputs[name][index] = value
        self._controlbox_di.clear()
        self._tool_di = self._analog_input_type = self._analog_input = None

    # ------------------------------------------------------------------ frame parts

    def controlbox_di(self, part_present: bool) -> tuple[bool, ...]:
        cached = self._controlbox_di.get(part_present)
        if cached is None:
            values = [bool(v) for v in self.inputs["controlbox_di"]]
            values[PART_PRESENT_DI_INDEX] = part_present
            cached = self._controlbox_di[part_present] = tuple(values)
        return cached

    def tool_di(self) -> tuple[bool, ...]:
        if self._tool_di is None:
            self._tool_di = tuple(bool(v) for v in self.inputs["tool_di"])
        return self._tool_di

    def analog_input_type(self) -> tuple[int, ...]:
        if self._analog_input_type is None:
            self._analog_input_type = tuple(int(v) for v in self.inputs["analog_input_type"])
        return self._analog_input_type

    def analog_input(self, noise: Sequence[float]) -> tuple[float, ...]:
        """The analog inputs plus ``noise`` (one value each, of ``analog_noise`` deviation)."""
        values = self._analog_input
        if values is None:
            values = self._analog_input = tuple(float(v) for v in self.inputs["analog_input"])
        return tuple([v + n for v, n in zip(values, noise, strict=True)])

    @property
    def analog_input_count(self) -> int:
        return len(self.inputs["analog_input"])

    def bit_output_registers(self, cycle_marker: bool = False) -> tuple[bool, ...]:
        """The registers the program writes: copies of the input registers, and the cycle
        marker in its register when there is one (each variant built once per command)."""
        applied = self.applied
        if applied is not self._registers_of:
            registers = applied.bit_input_registers
            self._registers = tuple(False if m is None else registers[m] for m in self.register_map)
            self._registers_of = applied
            self._marked.clear()
        marker = self.cycle_marker_register
        if marker is None:
            return self._registers
        marked = self._marked.get(cycle_marker)
        if marked is None:
            values = list(self._registers)
            values[marker] = cycle_marker
            marked = self._marked[cycle_marker] = tuple(values)
        return marked
