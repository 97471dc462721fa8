"""Verbs on the codec alone: ``decode``, ``encode-command`` and ``codegen``. No sockets."""

from __future__ import annotations

import argparse
import json
import sys
from typing import BinaryIO


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    decode = subparsers.add_parser(
        "decode",
        help="decode a T→O frame (284 bytes or more) to JSON",
        description="Decode a robot→PLC frame and print it as JSON. Exit 2 on a bad frame.",
    )
    decode.add_argument("file", nargs="?", default="-", help="binary frame, or - for stdin")
    decode.add_argument("--hex", action="store_true", help="the input is hex text")
    decode.set_defaults(handler=_decode)

    encode = subparsers.add_parser(
        "encode-command",
        help="turn a JSON command image (partial is fine) into the 20 O→T bytes",
        description=(
            "Read a JSON O→T command image: each field a full array or a map from index to "
            'value, e.g. {"controlbox_do": {"2": true}}; missing fields are zero. Write the 20 '
            "bytes (hex with --hex). Exit 2 on an unknown field, a bad index or value."
        ),
    )
    encode.add_argument("file", nargs="?", default="-", help="JSON file, or - for stdin")
    encode.add_argument("--hex", action="store_true", help="print hex instead of raw bytes")
    encode.set_defaults(handler=_encode_command)

    codegen = subparsers.add_parser(
        "codegen",
        help="regenerate the files derived from the layout table",
        description="Write frames.py, layout.json, layout.ts and docs/assembly.md.",
    )
    codegen.add_argument("--check", action="store_true", help="exit 1 if any file is stale")
    codegen.set_defaults(handler=_codegen)


def _read(path: str) -> bytes:
    if path == "-":
        stream: BinaryIO = sys.stdin.buffer
        return stream.read()
    with open(path, "rb") as file:
        return file.read()


def _fail(reason: str) -> int:
    print(f"cobot-hmi: {reason}", file=sys.stderr)
    return 2


def _decode(args: argparse.Namespace) -> int:
    from cobot_hmi.codec import CodecError, decode_frame, dumps, frame_to_json

    try:
        raw = _read(args.file)
    except OSError as error:
        return _fail(f"cannot read {args.file}: {error.strerror}")
    if args.hex:
        try:
            raw = bytes.fromhex("".join(raw.decode("ascii", "replace").split()))
        except ValueError as error:
            return _fail(f"bad hex input: {error}")
    try:
        frame = decode_frame(raw)
    except CodecError as error:
        return _fail(f"bad frame: {error}")
    sys.stdout.write(dumps(frame_to_json(frame)).decode() + "\n")
    return 0


def _encode_command(args: argparse.Namespace) -> int:
    from cobot_hmi.codec import CodecError, command_from_json, encode_command

    try:
        text = _read(args.file)
    except OSError as error:
        return _fail(f"cannot read {args.file}: {error.strerror}")
    try:
        data = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        return _fail(f"not JSON: {error}")
    try:
        wire = encode_command(command_from_json(data))
    except CodecError as error:
        return _fail(f"bad command image: {error}")
    if args.hex:
        sys.stdout.write(wire.hex() + "\n")
    else:
        sys.stdout.buffer.write(wire)
    return 0


def _codegen(args: argparse.Namespace) -> int:
    from cobot_hmi import codegen

    return codegen.main(["--check"] if args.check else [])
