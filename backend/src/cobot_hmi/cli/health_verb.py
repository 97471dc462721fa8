"""Layer: entry point. The ``health`` verb: ``cobot-hmi health simulate`` runs the health
engine on the emulated arm's program faster than real time and prints each joint's verdict and
figures as JSON (``joints`` as the service's health answer gives them). ``HealthSimulation``
is the same run for the tests. Imports the emulator's robot model and the health engine
inside the handler's reach only (``--help`` stays fast)."""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from cobot_hmi.emulator.robot.wear import JointWear

HEALTHY_COLD_FRICTION_PERCENT = 30.0
"""Every simulated gear's friction is this much higher cold (it settles as the motor warms):
a cold start must not read as wear."""
NIGHT_S = 12 * 3600.0


class HealthSimulation:
    """The engine fed the accelerated emulated arm, cycle by cycle, without sockets."""

    def __init__(
        self,
        arm: str = "M1013",
        seed: int = 1,
        start_s: float = 1_796_000_000.0,
        rate_hz: float = 100.0,
        cold_start: bool = False,
    ) -> None:
        import numpy as np

        from cobot_hmi.arms import arm_by_name
        from cobot_hmi.emulator.robot import RobotSettings
        from cobot_hmi.emulator.robot.accelerated import AcceleratedArm
        from cobot_hmi.emulator.robot.wear import JointWear, Wear
        from cobot_hmi.health import HealthEngine

        self.robot_settings = RobotSettings(model=arm, seed=seed)
        self.rate_hz = rate_hz
        self.arm = AcceleratedArm(self.robot_settings, rate_hz)
        self.engine = HealthEngine(arm_by_name(arm))
        self.rng = np.random.default_rng(seed)
        joints = len(self.arm.model.joints)
        self.healthy = JointWear(cold_friction_percent=HEALTHY_COLD_FRICTION_PERCENT)
        self.wear = Wear(joints)
        for j in range(joints):
            self.wear.set(j, self.healthy, start_s)
        self.now_s = start_s
        room = self.robot_settings.room_temperature_c
        self.temperatures = np.full(joints, room)
        if not cold_start:
            self.run(100, feed=False)  # warm: the motors settled at their duty

    def add_wear(self, joint: int, wear: JointWear) -> None:
        """Wear joint ``joint`` (1–6) from now (the healthy cold friction kept)."""
        self.wear.set(
            joint - 1,
            replace(wear, cold_friction_percent=HEALTHY_COLD_FRICTION_PERCENT),
            self.now_s,
        )

    def cool_down(self, seconds: float = NIGHT_S) -> None:
        """The robot stands still (a night): the motors cool towards the room."""
        room = self.robot_settings.room_temperature_c
        factor = math.exp(-seconds / self.robot_settings.thermal_time_constant_s)
        self.temperatures = room + (self.temperatures - room) * factor
        self.now_s += seconds

    def set_speed_fraction(self, fraction: float) -> None:
        """Another program speed (the cycle time changes)."""
        from cobot_hmi.emulator.robot.accelerated import AcceleratedArm

        self.arm = AcceleratedArm(
            replace(self.robot_settings, speed_fraction=fraction), self.rate_hz
        )

    def run(self, cycles: int, *, feed: bool = True) -> None:
        from cobot_hmi.health import FrameBlock

        for _ in range(cycles):
            frames = self.arm.cycle(self.now_s, self.temperatures, self.wear, self.rng)
            end_s = self.now_s + self.arm.duration_s
            if feed:
                self.engine.observe(FrameBlock(*frames))
                self.engine.end_cycle(self.now_s, end_s)
            self.temperatures = self.arm.end_temperatures(frames)
            self.now_s = end_s


_WEAR = re.compile(r"^([1-6]):([a-z_]+)=\+?(-?[0-9.]+)(%|c|nm)?$")
_WEAR_NAMES = {"friction": "friction_percent", "hot": "hot_c", "coulomb": "coulomb_nm"}


@dataclass(frozen=True)
class WearOption:
    joint: int
    field: str
    value: float


def _wear_option(text: str) -> WearOption:
    match = _WEAR.match(text.strip().lower())
    if match is None or match.group(2) not in _WEAR_NAMES:
        raise argparse.ArgumentTypeError(
            "expected JOINT:KIND=VALUE with KIND friction (%), hot (°C) or coulomb (N·m), "
            "e.g. 3:friction=+10%"
        )
    return WearOption(int(match.group(1)), _WEAR_NAMES[match.group(2)], float(match.group(3)))


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "health", help="robot health: run the engine on the emulated arm (docs/health.md)"
    )
    verbs = parser.add_subparsers(dest="health_verb", required=True, metavar="VERB")
    simulate = verbs.add_parser(
        "simulate",
        help="the health engine on the emulated arm's program, faster than real time",
        description=(
            "Learn a baseline from the first cycles of the emulated arm's program, run the rest "
            "with the wear given, and print each joint's verdict and figures as JSON."
        ),
    )
    simulate.add_argument("--arm", choices=("M1013", "M0609"), default="M1013")
    simulate.add_argument("--cycles", type=int, default=200, help="cycles after the baseline")
    simulate.add_argument("--baseline-cycles", type=int, default=50)
    simulate.add_argument(
        "--wear",
        type=_wear_option,
        action="append",
        default=[],
        metavar="J:KIND=VALUE",
        help="wear from the first cycle after the baseline, e.g. 3:friction=+10%%, 2:hot=8c",
    )
    simulate.add_argument(
        "--cold-start",
        action="store_true",
        help="start with the motors at room temperature (the gears' friction high) ",
    )
    simulate.add_argument("--seed", type=int, default=1)
    simulate.set_defaults(handler=_simulate)


def _simulate(args: argparse.Namespace) -> int:
    import orjson

    from cobot_hmi.emulator.robot.wear import JointWear

    if args.cycles < 1 or args.baseline_cycles < 1:
        print(
            "cobot-hmi health simulate: --cycles and --baseline-cycles must be 1 or more",
            file=sys.stderr,
        )
        return 2
    started = time.perf_counter()
    sim = HealthSimulation(args.arm, args.seed, cold_start=args.cold_start)
    sim.engine.begin_baseline(
        "cobot-hmi health simulate", "cobot-hmi", sim.now_s, cycles=args.baseline_cycles
    )
    sim.run(args.baseline_cycles)
    by_joint: dict[int, dict[str, float]] = {}
    for option in args.wear:
        by_joint.setdefault(option.joint, {})[option.field] = option.value
    for joint, values in by_joint.items():
        sim.add_wear(joint, JointWear(**values))
    sim.run(args.cycles)
    report = sim.engine.report()
    report["simulation"] = {
        "arm": args.arm,
        "cycles": args.cycles,
        "baseline_cycles": args.baseline_cycles,
        "cold_start": args.cold_start,
        "wear": [vars(option) for option in args.wear],
        "cycle_s": round(sim.arm.duration_s, 3),
        "simulated_s": round(sim.arm.duration_s * (args.cycles + args.baseline_cycles), 1),
        "wall_s": round(time.perf_counter() - started, 2),
    }
    sys.stdout.write(orjson.dumps(report, option=orjson.OPT_INDENT_2).decode() + "\n")
    return 0
