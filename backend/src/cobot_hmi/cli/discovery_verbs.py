"""Layer: entry point. ``discover`` (ListIdentity over UDP 44818, one JSON line per device) and
``eds`` (the emulated robot's Electronic Data Sheet). Imports the scanner's discovery client and
the emulator's EDS writer lazily, inside the handlers."""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    discover = subparsers.add_parser(
        "discover",
        help="find EtherNet/IP devices (ListIdentity over UDP 44818)",
        description=(
            "Send ListIdentity over UDP to each HOST and to each --broadcast address (with "
            "neither: to 255.255.255.255) and print one JSON line per device that answers "
            "within --timeout: address, vendor, device type, product code, revision, serial, "
            "product name, status, state. Exit 0 if any answered, 1 if none."
        ),
    )
    discover.add_argument("hosts", nargs="*", metavar="HOST", help="ask these addresses")
    discover.add_argument(
        "--broadcast",
        action="append",
        default=[],
        metavar="ADDR",
        help="broadcast to ADDR, e.g. the cell network's 192.0.2.255 (repeatable)",
    )
    discover.add_argument(
        "--timeout",
        type=float,
        default=2.0,
        metavar="S",
        help="how long to wait for answers (default 2; devices answer a broadcast within "
        "the max delay, half of it by default)",
    )
    discover.add_argument(
        "--max-delay-ms",
        type=int,
        default=None,
        metavar="MS",
        help="MaxResponseDelay asked of devices answering a broadcast (default: half the "
        "timeout; devices take at least 500 ms)",
    )
    discover.add_argument("--port", type=int, default=44818, help="UDP port (default 44818)")
    discover.add_argument("--local-host", default="0.0.0.0", help="local address (default all)")
    discover.set_defaults(handler=_discover)

    eds = subparsers.add_parser(
        "eds",
        help="write the emulated robot's Electronic Data Sheet (EDS)",
        description=(
            "Write the EDS of the emulated robot's EtherNet/IP adapter (identity, assemblies "
            "100/150/151/198/199, exclusive-owner, input-only and listen-only connections, RPI "
            "range), generated from the layout, for a PLC programming tool (docs/operations.md)."
        ),
    )
    eds.add_argument("-o", "--output", default=None, metavar="FILE", help="default: stdout")
    eds.add_argument(
        "--model",
        choices=("M1013", "M0609"),
        default="M1013",
        help="the emulated arm whose identity the EDS carries (as the emulator's --model)",
    )
    eds.set_defaults(handler=_eds)


def _discover(args: argparse.Namespace) -> int:
    import asyncio
    import sys

    from cobot_hmi.codec import dumps
    from cobot_hmi.scanner.discovery import LIMITED_BROADCAST, discover

    if args.timeout <= 0:
        print("cobot-hmi discover: --timeout must be positive", file=sys.stderr)
        return 2
    broadcast = list(args.broadcast)
    if not args.hosts and not broadcast:
        broadcast = [LIMITED_BROADCAST]
    try:
        result = asyncio.run(
            discover(
                args.hosts,
                broadcast,
                timeout_s=args.timeout,
                port=args.port,
                local_host=args.local_host,
                max_delay_ms=args.max_delay_ms,
            )
        )
    except (OSError, ValueError) as error:
        print(f"cobot-hmi discover: {error}", file=sys.stderr)
        return 2
    for device in sorted(result.devices, key=lambda d: d.address):
        sys.stdout.write(dumps(device.to_json()).decode() + "\n")
    sys.stdout.flush()
    if not result.devices:
        print("cobot-hmi discover: no device answered", file=sys.stderr)
        return 1
    return 0


def _eds(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from cobot_hmi.emulator.eds import eds_text
    from cobot_hmi.emulator.target_settings import TargetSettings, default_identity

    text = eds_text(TargetSettings(identity=default_identity(args.model)))
    if args.output is None or args.output == "-":
        sys.stdout.write(text)
        return 0
    try:
        Path(args.output).write_text(text, encoding="ascii")
    except OSError as error:
        print(f"cobot-hmi eds: {error}", file=sys.stderr)
        return 1
    print(f"wrote {args.output}", file=sys.stderr)
    return 0
