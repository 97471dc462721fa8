"""Layer: entry point. The ``emulator`` verb: the robot's EtherNet/IP target until SIGINT or
SIGTERM. Imports the emulator lazily, inside the handler."""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import TYPE_CHECKING, cast

from cobot_hmi.layout import CONNECTION_POINTS, O2T_ASSEMBLY, T2O_ASSEMBLY

if TYPE_CHECKING:
    from cobot_hmi.emulator.process_image import ProcessImage
    from cobot_hmi.emulator.replay_robot import ReplayRobot
    from cobot_hmi.emulator.robot.wear import WearScenario
    from cobot_hmi.emulator.target_settings import TargetSettings


def _rpi_range(text: str) -> tuple[int, int]:
    try:
        low, high = (int(float(part) * 1000) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError("expected MIN_MS,MAX_MS, e.g. 1,10000") from None
    if not 0 < low <= high:
        raise argparse.ArgumentTypeError("expected 0 < MIN_MS <= MAX_MS")
    return low, high


def _vendor_id(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError("expected a number, e.g. 1573 or 0xFFFE") from None
    if not 0 <= value <= 0xFFFF:
        raise argparse.ArgumentTypeError("expected 0 to 65535 (0xFFFF)")
    return value


def _temperature_rise_c(text: str) -> float:
    from cobot_hmi.emulator.robot.wear import MAX_MOTOR_TEMPERATURE_RISE_C as MAX_C

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError("expected °C, e.g. 40 or 0") from None
    if not 0.0 <= value <= MAX_C:
        raise argparse.ArgumentTypeError(f"expected 0 to {MAX_C:g} °C")
    return value


def _register_map(text: str) -> tuple[int | None, ...]:
    from cobot_hmi.emulator.robot.robot_io import parse_register_map

    try:
        return parse_register_map(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _output_register(text: str) -> int:
    from cobot_hmi.emulator.robot.robot_io import output_register

    try:
        return output_register(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    parser = subparsers.add_parser(
        "emulator",
        help="run the emulated robot's EtherNet/IP target (TCP 44818, UDP 2222)",
        description=(
            "Serve the robot's EtherNet/IP adapter: explicit messages, Forward Open and class 1 "
            "cyclic I/O. Runs until SIGINT or SIGTERM."
        ),
    )
    _add_target_arguments(parser)
    _add_hardening_arguments(parser)
    parser.add_argument(
        "--idle",
        choices=("hold", "clear"),
        default="hold",
        help="outputs when the owner goes idle or times out (default hold)",
    )
    robot = parser.add_argument_group("the simulated robot (docs/emulator.md)")
    _add_robot_arguments(robot)
    _add_control_arguments(robot)
    parser.add_argument("-v", "--verbose", action="store_true", help="log connections")
    parser.set_defaults(handler=_run)


def _add_target_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the target listens, its assemblies and their sizes, the RPIs it accepts."""
    parser.add_argument("--host", default="127.0.0.2", help="address to bind (default 127.0.0.2)")
    parser.add_argument("--tcp-port", type=int, default=44818)
    parser.add_argument("--udp-port", type=int, default=2222)
    points = CONNECTION_POINTS
    parser.add_argument("--config-instance", type=int, default=points.configuration)
    parser.add_argument("--o2t-instance", type=int, default=points.o2t)
    parser.add_argument("--t2o-instance", type=int, default=points.t2o)
    parser.add_argument("--input-only-instance", type=int, default=points.input_only)
    parser.add_argument("--listen-only-instance", type=int, default=points.listen_only)
    for option, arrow, assembly in (("o2t", "O→T", O2T_ASSEMBLY), ("t2o", "T→O", T2O_ASSEMBLY)):
        parser.add_argument(
            f"--{option}-size",
            type=int,
            default=assembly.size_bytes,
            help=f"{arrow} data bytes (default {assembly.size_bytes})",
        )
    parser.add_argument(
        "--rpi-range-ms",
        type=_rpi_range,
        default=(1_000, 10_000_000),
        metavar="MIN,MAX",
        help="accepted RPI range in ms (default 1,10000)",
    )
    parser.add_argument("--max-connections", type=int, default=8)


def _add_hardening_arguments(parser: argparse.ArgumentParser) -> None:
    """Its bounds (sessions, stalled messages, silent sessions) and discovery."""
    hardening = parser.add_argument_group("bounds and discovery (docs/operations.md)")
    hardening.add_argument(
        "--max-tcp-sessions",
        type=int,
        default=64,
        metavar="N",
        help="TCP connections on the encapsulation port at once; more are closed (default 64)",
    )
    hardening.add_argument(
        "--incomplete-message-timeout-s",
        type=float,
        default=10.0,
        metavar="S",
        help="drop a connection whose message stalls this long (default 10)",
    )
    hardening.add_argument(
        "--session-inactivity-timeout-s",
        type=float,
        default=120.0,
        metavar="S",
        help="close a registered session silent this long (default 120; 0: never)",
    )
    hardening.add_argument(
        "--no-discovery", action="store_true", help="no ListIdentity/ListServices on UDP 44818"
    )
    hardening.add_argument(
        "--discovery-broadcast",
        action="append",
        default=None,
        metavar="ADDR",
        help="also answer discovery broadcast to ADDR (repeatable; default: 127.255.255.255 "
        "for a loopback --host, 255.255.255.255 otherwise, none for 0.0.0.0)",
    )


def _add_robot_arguments(robot: argparse._ArgumentGroup) -> None:
    """The robot behind the target: the simulation (its model, program, wear), a replay."""
    robot.add_argument("--model", choices=("M1013", "M0609"), default="M1013")
    robot.add_argument(
        "--vendor-id",
        type=_vendor_id,
        default=None,
        help="the Identity object's vendor ID (default 1573, Doosan Robotics in ODVA's list)",
    )
    robot.add_argument(
        "--static", action="store_true", help="a robot that stands still instead of the simulation"
    )
    robot.add_argument(
        "--replay",
        type=Path,
        default=None,
        metavar="FILE",
        help="play a recording (a history export: Parquet or MCAP) back as the T→O stream "
        "instead of the simulation (docs/emulator.md)",
    )
    robot.add_argument(
        "--speed", type=float, default=1.0, metavar="X", help="--replay: X times real time"
    )
    robot.add_argument("--loop", action="store_true", help="--replay: start again at the end")
    robot.add_argument(
        "--max-lag-s",
        type=float,
        default=1.0,
        metavar="S",
        help="--replay: send every recorded frame in order while at most S seconds behind "
        "the recording's clock; further behind, skip to the instant's frame (default 1)",
    )
    robot.add_argument("--seed", type=int, default=1, help="seed of the simulation's noise")
    robot.add_argument(
        "--wear",
        type=Path,
        metavar="FILE",
        help="a wear scenario (JSON) the simulated robot starts with (docs/emulator.md, Wear)",
    )
    robot.add_argument(
        "--no-program", action="store_true", help="do not start the demo program by itself"
    )
    robot.add_argument("--collaborative", action="store_true", help="start in collaborative mode")
    robot.add_argument(
        "--kinematic-refresh-ms",
        type=float,
        default=100.0,
        metavar="MS",
        help="refresh the monitoring values (joints, TCP, currents, analog inputs) every MS: "
        "default 100, as the real controller does whatever the RPI (docs/emulator.md); "
        "0: every frame",
    )
    robot.add_argument(
        "--motor-temperature-rise-c",
        type=_temperature_rise_c,
        default=None,
        metavar="C",
        help="how many °C above room temperature (25 °C) a motor settles at its rated current "
        "(default 40); 0 holds every motor at room temperature, so a test's friction reads in "
        "one temperature band from the start (docs/emulator.md)",
    )
    robot.add_argument(
        "--register-map",
        type=_register_map,
        default=None,
        metavar="OUT=IN,...",
        help="bit output register OUT copies bit input register IN (default: n copies n; "
        "OUT=- keeps OUT off)",
    )
    robot.add_argument(
        "--cycle-marker-register",
        type=_output_register,
        default=None,
        metavar="N",
        help="the demo program sets bit output register N from the start of each cycle through "
        "its first steps (the cycle-start marker; cobot-hmi demo uses 63); default: no marker",
    )


def _add_control_arguments(robot: argparse._ArgumentGroup) -> None:
    """The test hooks' HTTP API (docs/emulator.md, Control API)."""
    robot.add_argument(
        "--control-port",
        type=int,
        default=8081,
        help="control API port on --host (default 8081; 0 picks a free one)",
    )
    robot.add_argument("--no-control-api", action="store_true", help="serve no control API")
    robot.add_argument(
        "--control-token",
        default=os.environ.get("COBOT_HMI_EMULATOR_CONTROL_TOKEN") or None,
        metavar="TOKEN",
        help="require 'Authorization: Bearer TOKEN' on the control API "
        "(default: $COBOT_HMI_EMULATOR_CONTROL_TOKEN; none: no token)",
    )
    robot.add_argument(
        "--control-allowed-host",
        action="append",
        default=[],
        metavar="NAME",
        help="a host name the control API answers to besides IP addresses, localhost and "
        "this machine's names (repeatable)",
    )


def _wear_scenario(path: Path, joints: int) -> WearScenario | None:
    """The scenario file, read before the robot is built (it may shape the motors' heating);
    None (said why) when it is unusable."""
    import json

    from cobot_hmi.emulator.robot.wear import WearError, parse_scenario

    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return parse_scenario(data, joints)
    except (OSError, ValueError) as error:  # WearError and JSONDecodeError are ValueErrors
        kind = "wear scenario" if isinstance(error, WearError) else "cannot read"
        print(f"cobot-hmi emulator: --wear {path}: {kind}: {error}", flush=True)
        return None


def _run(args: argparse.Namespace) -> int:
    import asyncio
    import logging

    from cobot_hmi.eventloop import precise_event_loop

    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(asctime)s %(name)s %(message)s",
    )
    settings = _target_settings(args)
    robot = _robot(args)
    if isinstance(robot, int):
        return robot
    try:
        with asyncio.Runner(loop_factory=precise_event_loop) as runner:
            runner.run(_serve(args, settings, robot))
    except OSError as error:
        print(f"cobot-hmi emulator: {error}", flush=True)
        return 1
    return 0


def _target_settings(args: argparse.Namespace) -> TargetSettings:
    from cobot_hmi.emulator.process_image import IdleBehaviour
    from cobot_hmi.emulator.target_settings import (
        DOOSAN_VENDOR_ID,
        TargetSettings,
        default_identity,
    )

    return TargetSettings(
        host=args.host,
        tcp_port=args.tcp_port,
        udp_port=args.udp_port,
        config_instance=args.config_instance,
        o2t_instance=args.o2t_instance,
        t2o_instance=args.t2o_instance,
        input_only_instance=args.input_only_instance,
        listen_only_instance=args.listen_only_instance,
        o2t_size=args.o2t_size,
        t2o_size=args.t2o_size,
        rpi_min_us=args.rpi_range_ms[0],
        rpi_max_us=args.rpi_range_ms[1],
        max_connections=args.max_connections,
        idle_behaviour=IdleBehaviour(args.idle),
        max_tcp_sessions=args.max_tcp_sessions,
        incomplete_message_timeout_s=args.incomplete_message_timeout_s,
        session_inactivity_timeout_s=args.session_inactivity_timeout_s or None,
        discovery=not args.no_discovery,
        discovery_broadcast_hosts=(
            tuple(args.discovery_broadcast) if args.discovery_broadcast is not None else None
        ),
        control_token=args.control_token,
        identity=default_identity(
            args.model, DOOSAN_VENDOR_ID if args.vendor_id is None else args.vendor_id
        ),
    )


def _robot(args: argparse.Namespace) -> ProcessImage | int:
    """The robot behind the target: a replay, a robot standing still or the simulation; an exit
    status (2, said why) when the arguments cannot make one."""
    import time

    from cobot_hmi.emulator.process_image import IdleBehaviour
    from cobot_hmi.emulator.robot import RobotSettings, SimulatedRobot
    from cobot_hmi.emulator.robot.models import model_by_name
    from cobot_hmi.emulator.static_robot import StaticRobot

    idle = IdleBehaviour(args.idle)
    if args.replay is not None:
        return _replay_robot(args)
    if args.static:
        return StaticRobot(idle)
    scenario = None
    if args.wear is not None:
        scenario = _wear_scenario(args.wear, len(model_by_name(args.model).joints))
        if scenario is None:
            return 2
    settings = RobotSettings(
        model=args.model,
        seed=args.seed,
        autostart_program=not args.no_program,
        collaborative=args.collaborative,
        idle_behaviour=idle,
        kinematic_refresh_ms=args.kinematic_refresh_ms,
        register_map=args.register_map,
        cycle_marker_register=args.cycle_marker_register,
    )
    # The command line's rise over the scenario file's; set only when one says it, so that
    # RobotSettings' own default stays the one place it is said.
    rise_c = args.motor_temperature_rise_c
    if rise_c is None and scenario is not None:
        rise_c = scenario.motor_temperature_rise_c
    if rise_c is not None:
        settings.temperature_rise_at_rated_current_c = rise_c
    simulated = SimulatedRobot(settings)
    if scenario is not None:
        scenario.apply(simulated.wear, time.time())
    return simulated


def _replay_robot(args: argparse.Namespace) -> ProcessImage | int:
    from cobot_hmi.emulator.replay_robot import ReplayRobot
    from cobot_hmi.history.recording import RecordingError, read_recording

    if not args.speed > 0:
        print("cobot-hmi emulator: --speed must be above 0", flush=True)
        return 2
    if not args.max_lag_s >= 0:
        print("cobot-hmi emulator: --max-lag-s must be 0 or more", flush=True)
        return 2
    try:
        recording = read_recording(args.replay)
    except RecordingError as error:
        print(f"cobot-hmi emulator: {error}", flush=True)
        return 2
    return ReplayRobot(recording, speed=args.speed, loop=args.loop, max_lag_s=args.max_lag_s)


async def _serve(args: argparse.Namespace, settings: TargetSettings, robot: ProcessImage) -> None:
    """The target (and its discovery and control API) until SIGINT or SIGTERM."""
    import asyncio
    import signal

    from cobot_hmi.emulator.control_api import ControlApiServer, create_control_app
    from cobot_hmi.emulator.discovery import DiscoveryServer
    from cobot_hmi.emulator.robot import SimulatedRobot
    from cobot_hmi.emulator.target import Target
    from cobot_hmi.eventloop import freeze_startup_heap

    target = Target(settings, robot)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    await target.start()
    control = None
    discovery = None
    try:
        if settings.discovery:
            discovery = DiscoveryServer(
                target, args.host, settings.discovery_port, settings.discovery_broadcast_hosts
            )
            await discovery.start()
        if isinstance(robot, SimulatedRobot) and not args.no_control_api:
            control = ControlApiServer(
                create_control_app(
                    robot,
                    target,
                    token=settings.control_token,
                    allowed_hosts=args.control_allowed_host,
                    discovery=discovery,
                ),
                args.host,
                args.control_port,
            )
            await control.start()
        print(
            f"cobot-hmi emulator: EtherNet/IP target on {args.host} "
            f"TCP {target.tcp_port} UDP {target.udp_port}"
            + (f", discovery UDP {discovery.port}" if discovery else "")
            + (f", control API http://{args.host}:{control.port}" if control else ""),
            flush=True,
        )
        freeze_startup_heap()
        await stop.wait()
    finally:
        if control is not None:
            await control.stop()
        if discovery is not None:
            discovery.stop()
        await target.stop()
        if args.replay is not None:  # how the re-run went: frames sent, any skipped
            print(f"cobot-hmi emulator: {cast('ReplayRobot', robot).summary()}", flush=True)
