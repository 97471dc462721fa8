"""Layer: entry point. The ``export`` verb: a range of a robot's recording as CSV, Parquet or MCAP,
read from a state directory (the service need not run; a running one keeps recording). The same
bytes as ``GET /api/v1/robots/{name}/export`` (docs/api.md, History). Imports lazily, inside the
handler.
"""

from __future__ import annotations

import argparse
import sys


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    from cobot_hmi.cli.hmi_settings import add_hmi_arguments

    parser = subparsers.add_parser(
        "export",
        help="export a robot's recorded frames (CSV, Parquet, MCAP) from a state directory",
        description="Write a range of a robot's recording as a file: CSV (one column per "
        "element, units in the header, ISO 8601 times), Parquet (the recording's columns) or "
        "MCAP (frames and events as JSON channels with JSON Schemas, for Foxglove/Lichtblick). "
        "Times: ISO 8601 (no offset: UTC) or seconds since the epoch.",
    )
    parser.add_argument("--robot", help="the robot's name (default: the only one recorded)")
    parser.add_argument("--from", dest="from_", required=True, metavar="TIME", help="range start")
    parser.add_argument("--to", required=True, metavar="TIME", help="range end (excluded)")
    parser.add_argument("--format", choices=("csv", "parquet", "mcap"), default="csv")
    parser.add_argument(
        "--fields", default=None, help="comma-separated fields or elements (default: all)"
    )
    parser.add_argument(
        "-o",
        "--output",
        default=None,
        metavar="FILE",
        help="where to write ('-': standard output; default: ROBOT_FROM_TO.FORMAT here)",
    )
    add_hmi_arguments(parser, only=("state_dir", "history_dir", "database"))
    parser.set_defaults(handler=_export)


def _fail(message: str) -> int:
    print(f"cobot-hmi export: {message}", file=sys.stderr)
    return 2


def _export(args: argparse.Namespace) -> int:
    import contextlib
    from pathlib import Path

    from cobot_hmi.cli.hmi_settings import hmi_settings
    from cobot_hmi.history import export
    from cobot_hmi.history.schema import UnknownFieldError, select_elements
    from cobot_hmi.history.segments import list_robots
    from cobot_hmi.history.times import TimeFormatError, parse_time
    from cobot_hmi.service.api.routes.history import export_chunks
    from cobot_hmi.service.plant_time import host_zone_name
    from cobot_hmi.service.service_settings import SettingsError

    try:
        settings = hmi_settings(args)
    except SettingsError as error:
        return _fail(str(error))
    root = settings.history_path
    robots = list_robots(root)
    robot = args.robot
    if robot is None:
        if len(robots) != 1:
            known = ", ".join(robots) or "none"
            return _fail(f"name the robot with --robot (recorded under {root}: {known})")
        robot = robots[0]
    elif robot not in robots:
        return _fail(f"no recording of robot {robot!r} under {root} (recorded: "
                     f"{', '.join(robots) or 'none'})")  # fmt: skip
    try:
        from_s, to_s = parse_time(args.from_), parse_time(args.to)
        elements = select_elements(args.fields.split(",") if args.fields else None)
    except (TimeFormatError, UnknownFieldError) as error:
        return _fail(str(error))
    if to_s <= from_s:
        return _fail("--to must be after --from")
    output = args.output or export.export_filename(robot, from_s, to_s, args.format)
    chunks = export_chunks(
        root,
        settings.web.database_path,
        robot,
        elements,
        from_s=from_s,
        to_s=to_s,
        fmt=args.format,
        zone=settings.site.time_zone or host_zone_name(),  # the plant's, as the service writes it
    )
    try:
        with contextlib.ExitStack() as stack:
            if output == "-":
                sink = sys.stdout.buffer
            else:
                sink = stack.enter_context(Path(output).open("wb"))
            for chunk in chunks:
                sink.write(chunk)
            sink.flush()
    except OSError as error:
        return _fail(f"cannot write {output}: {error.strerror or error}")
    if output != "-":
        print(output)
    return 0
