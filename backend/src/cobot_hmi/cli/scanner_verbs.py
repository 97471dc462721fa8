"""Layer: entry point. The originator's verbs: ``probe`` (explicit reads through pycomm3) and
``scan`` (a class 1 connection, one JSON line per frame or per second). Imports the scanner
lazily, inside the handlers.

Both work against any adapter (issue 11): instances and sizes are arguments, the robot's layout
only their default; data shorter than the robot's frame (or with ``--raw``) is printed as hex,
and decoded to the robot's frame only at the layout's size or longer (appended registers)."""

from __future__ import annotations

import argparse
import contextlib
import itertools
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

from cobot_hmi.layout import CONNECTION_POINTS, O2T_ASSEMBLY, T2O_ASSEMBLY

if TYPE_CHECKING:  # the scanner is imported inside the handlers, when a verb runs
    from cobot_hmi.codec import Frame
    from cobot_hmi.scanner.originator import ConnectionState, ConnectionStats, OriginatorSettings
    from cobot_hmi.scanner.t2o_pace import SlowTarget

_DEFAULT_INSTANCES = (CONNECTION_POINTS.configuration, CONNECTION_POINTS.o2t, CONNECTION_POINTS.t2o)
_DEFAULT_SIZES = (O2T_ASSEMBLY.size_bytes, T2O_ASSEMBLY.size_bytes)


def _int_list(count: int, what: str) -> Callable[[str], tuple[int, ...]]:
    def parse(text: str) -> tuple[int, ...]:
        try:
            values = tuple(int(part) for part in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}") from None
        if len(values) != count or any(v < 0 for v in values):
            raise argparse.ArgumentTypeError(f"expected {what}")
        return values

    return parse


def _hex_bytes(text: str) -> bytes:
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise argparse.ArgumentTypeError("expected hexadecimal bytes, e.g. 0102ff") from None


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    _register_probe(subparsers)
    _register_scan(subparsers)


def _register_probe(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    probe = subparsers.add_parser(
        "probe",
        help="read a robot's identity, assembly sizes and one T→O frame explicitly",
        description="Explicit reads (pycomm3): ListIdentity, assembly sizes, one T→O frame.",
    )
    probe.add_argument("host")
    probe.add_argument("--port", type=int, default=44818, help="TCP port (default 44818)")
    probe.add_argument("--o2t-instance", type=int, default=CONNECTION_POINTS.o2t)
    probe.add_argument("--t2o-instance", type=int, default=CONNECTION_POINTS.t2o)
    probe.add_argument(
        "--sizes",
        type=_int_list(2, "o2t,t2o"),
        default=None,
        metavar="O2T,T2O",
        help="the data sizes expected, in bytes: exit 1 when the adapter reports others",
    )
    probe.add_argument("--raw", action="store_true", help="never decode the T→O data as a frame")
    probe.set_defaults(handler=_probe)


def _register_scan(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    scan = subparsers.add_parser(
        "scan",
        help="hold a class 1 connection and print the frames",
        description=(
            "Hold a class 1 connection (exclusive owner, or --input-only) to any adapter and "
            "print one JSON line per frame (the robot's frame when T→O has its layout's size or "
            "more, else the data as hex), or per second with --stats, then a summary with the "
            "counters. The connection sends IDLE from start to end (run/idle header, run bit "
            "0): the adapter receives every O→T packet but does not apply its data to its "
            "outputs, which it holds or clears as its idle behaviour says. Exit 0 if the "
            "connection held, 2 if it was refused, 3 if it was lost or never came up."
        ),
        epilog=(
            "Counters: gaps = T→O packets lost on the way (CIP sequence count jumps); "
            "duplicates = packets repeating the count (no new data); late = frames more than "
            "1.5 × the granted T→O interval (API) after the one before, for whatever reason; "
            "slow_target = the adapter sends T→O less often than it granted (median over a "
            "second above 1.5 × API), said once in words on stderr and in the summary, and "
            "once more when it keeps its grant again."
        ),
    )
    scan.add_argument("host")
    scan.add_argument("--port", type=int, default=44818, help="TCP port (default 44818)")
    scan.add_argument("--rpi-ms", type=float, default=10.0, help="RPI in ms (default 10)")
    scan.add_argument("--seconds", type=float, default=None, help="stop after N s (else ^C)")
    scan.add_argument("--input-only", action="store_true", help="read-only: never own outputs")
    scan.add_argument(
        "--instances",
        type=_int_list(3, "cfg,o2t,t2o"),
        default=_DEFAULT_INSTANCES,
        metavar="CFG,O2T,T2O",
        help="assembly instances (default {},{},{})".format(*_DEFAULT_INSTANCES),
    )
    scan.add_argument(
        "--sizes",
        type=_int_list(2, "o2t,t2o"),
        default=_DEFAULT_SIZES,
        metavar="O2T,T2O",
        help=(
            "data sizes in bytes, in the Forward Open and in every O→T packet (default {},{}: "
            "the robot's; shorter T→O is printed as hex)".format(*_DEFAULT_SIZES)
        ),
    )
    scan.add_argument(
        "--raw", action="store_true", help="print T→O data as hex even at the robot's size"
    )
    scan.add_argument(
        "--o2t-hex",
        type=_hex_bytes,
        default=None,
        metavar="HEX",
        help=(
            "O→T data, zero-filled to the O→T size, in every O→T packet as given until the "
            "scan ends (default: the O→T assembly's, read first where the adapter allows it; "
            "at the robot's sizes, the robot's outputs from the first frame: bumpless "
            "takeover). Sent idle: the adapter does not apply it to its outputs"
        ),
    )
    scan.add_argument(
        "--api-range-us",
        type=_int_list(2, "min,max"),
        default=None,
        metavar="MIN,MAX",
        help="packet intervals a target may grant (default RPI/2 to RPI×2)",
    )
    scan.add_argument("--heartbeat-instance", type=int, default=CONNECTION_POINTS.input_only)
    scan.add_argument("--multiplier", type=int, default=2, help="timeout multiplier (2: RPI×16)")
    scan.add_argument("--large", action="store_true", help="use a Large Forward Open")
    scan.add_argument("--stats", action="store_true", help="one line of statistics per second")
    scan.add_argument(
        "--local-host",
        default=None,
        help="local address (default: the one that routes to the target; 0.0.0.0: all)",
    )
    scan.add_argument("--t2o-port", type=int, default=None, help="ask for T→O on this port")
    scan.set_defaults(handler=_scan)


def _probe(args: argparse.Namespace) -> int:
    from cobot_hmi.codec import dumps, frame_to_json
    from cobot_hmi.scanner.explicit import ExplicitError, probe

    try:
        result = probe(
            args.host,
            args.port,
            o2t_instance=args.o2t_instance,
            t2o_instance=args.t2o_instance,
            raw=args.raw,
        )
    except ExplicitError as error:
        print(f"cobot-hmi probe: {error}", file=sys.stderr)
        return 1
    identity = {k: (v.hex() if isinstance(v, bytes) else v) for k, v in result.identity.items()}
    out: dict[str, object] = {
        "identity": identity,
        "assembly_sizes": {
            str(args.o2t_instance): result.o2t_size,
            str(args.t2o_instance): result.t2o_size,
        },
        "t2o_data_hex": result.t2o_data.hex(),
        "t2o_frame": frame_to_json(result.frame) if result.frame is not None else None,
    }
    code = 0
    if result.frame_error:
        out["t2o_frame_error"] = result.frame_error
        code = 1
    if args.sizes is not None:
        o2t_size, t2o_size = args.sizes
        # The T→O data read is the size's proof where the size attribute is not served.
        found_t2o = result.t2o_size if result.t2o_size is not None else len(result.t2o_data)
        matches = found_t2o == t2o_size and result.o2t_size in (None, o2t_size)
        out["sizes_expected"] = {str(args.o2t_instance): o2t_size, str(args.t2o_instance): t2o_size}
        out["sizes_match"] = matches
        if not matches:
            code = 1
    sys.stdout.write(dumps(out).decode() + "\n")
    return code


def _scan(args: argparse.Namespace) -> int:
    import asyncio

    from cobot_hmi.eventloop import precise_event_loop

    with asyncio.Runner(loop_factory=precise_event_loop) as runner:
        return runner.run(_scan_until_stopped(args, _ScanPrinter(args.stats)))


def _scan_settings(args: argparse.Namespace) -> OriginatorSettings:
    from cobot_hmi.scanner.originator import OriginatorSettings

    cfg, o2t, t2o = args.instances
    o2t_size, t2o_size = args.sizes
    return OriginatorSettings(
        robot_host=args.host,
        tcp_port=args.port,
        local_host=args.local_host,
        rpi_us=round(args.rpi_ms * 1000),
        timeout_multiplier=args.multiplier,
        input_only=args.input_only,
        large_forward_open=args.large,
        config_instance=cfg,
        o2t_instance=o2t,
        t2o_instance=t2o,
        heartbeat_instance=args.heartbeat_instance,
        o2t_size=o2t_size,
        t2o_size=t2o_size,
        request_t2o_port=args.t2o_port,
        o2t_data=args.o2t_hex,
        raw=args.raw,
        api_bounds_us=args.api_range_us,
    )


class _ScanPrinter:
    """What ``scan`` prints: a JSON line per frame (or per second with ``--stats``) on stdout,
    the connection's states and a slow target in words on stderr."""

    def __init__(self, stats_only: bool) -> None:
        self.stats_only = stats_only
        self.out = sys.stdout
        self.seen: set[ConnectionState] = set()
        # ``seq`` in the lines counts the frames delivered (1, 2, …), as it always has; the
        # callbacks' own third argument is the packet's wire sequence number.
        self._delivered = itertools.count(1)
        self._slow: list[SlowTarget] = []

    def on_frame(self, frame: Frame, _payload: bytes, received_at: float, _seq: int) -> None:
        from cobot_hmi.codec import frame_to_json

        seq = next(self._delivered)
        if not self.stats_only:
            self.line({"seq": seq, "received_at": received_at, "frame": frame_to_json(frame)})

    def on_data(self, data: bytes, received_at: float, _t2o_sequence: int) -> None:
        seq = next(self._delivered)
        if not self.stats_only:
            self.line({"t": received_at, "seq": seq, "data_hex": data.hex()})

    def on_state(self, state: ConnectionState, reason: str | None) -> None:
        self.seen.add(state)
        print(f"cobot-hmi scan: {state}{': ' + reason if reason else ''}", file=sys.stderr)

    def on_slow_target(self, slow: SlowTarget | None) -> None:
        if slow is not None:
            self._slow.append(slow)
            print(f"cobot-hmi scan: {slow.words()}", file=sys.stderr)
        elif self._slow:
            print(f"cobot-hmi scan: {self._slow[-1].kept_words()}", file=sys.stderr)

    def line(self, document: dict[str, object]) -> None:
        from cobot_hmi.codec import dumps

        self.out.write(dumps(document).decode() + "\n")

    @staticmethod
    def stats_json(stats: ConnectionStats) -> dict[str, object]:
        """The counters, the slow target in words (null while it keeps its grant)."""
        from dataclasses import asdict

        slow = stats.slow_target
        return {**asdict(stats), "slow_target": slow.words() if slow is not None else None}


async def _scan_until_stopped(args: argparse.Namespace, printer: _ScanPrinter) -> int:
    """Hold the connection until ^C, SIGTERM or ``--seconds``; the exit status."""
    import asyncio
    import signal
    import time

    from cobot_hmi.eventloop import freeze_startup_heap
    from cobot_hmi.scanner.originator import ConnectionState, Originator

    try:
        originator = Originator(
            _scan_settings(args),
            on_frame=printer.on_frame,
            on_state=printer.on_state,
            on_data=printer.on_data,
            on_slow_target=printer.on_slow_target,
        )
    except ValueError as error:  # --o2t-hex longer than O→T, or not a command image
        print(f"cobot-hmi scan: {error}", file=sys.stderr)
        return 1
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    end = loop.time() + args.seconds if args.seconds is not None else None
    freeze_startup_heap()
    await originator.start()
    try:
        while not stop.is_set():
            remaining = 1.0 if end is None else min(1.0, end - loop.time())
            if remaining <= 0:
                break
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), remaining)
            if args.stats:
                printer.line({"t": time.time(), **printer.stats_json(originator.stats())})
            printer.out.flush()
        summary = printer.stats_json(originator.stats())
    finally:
        await originator.stop()
    printer.line({"summary": summary})
    printer.out.flush()
    if ConnectionState.REFUSED in printer.seen:
        return 2
    if ConnectionState.LOST in printer.seen or summary["state"] != ConnectionState.CONNECTED:
        return 3
    return 0
