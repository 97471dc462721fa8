"""Codec benchmark (see bench/codec). Prints figures and the targets they are held against.

Targets (issue 2): at least 100,000 decodes/s on one core, and decode within 5x of the floor, a
bare ``struct.unpack_from`` of the same 284 bytes (the layout's own compiled struct, so the
floor is reading the values and nothing else).

The floor's format is the spec's own word view of the 284 bytes (shared/spec/assembly.md),
written here independently of the codec: DWORD 0, DWORD 4, four REALs, DWORD 24, three USINTs,
the state USINT, the flag WORD at 34, sixty REALs and the two register DWORDs.
"""

from __future__ import annotations

import os
import statistics
import struct
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "backend" / "tests"))

from cobot_hmi.codec import decode_frame, dumps, encode_frame, frame_to_json
from golden_vectors import t2o_vectors

TARGET_DECODES_PER_S = 100_000
TARGET_RATIO_TO_BARE = 5.0
ROUNDS = 5
SPEC_WORD_VIEW = struct.Struct("<II4fI3BxBxH60f2I")


def per_call_us(work: Callable[[], None], calls: int) -> float:
    """Median over rounds of the time per call, in µs (the loop's own cost included)."""
    samples = []
    for _ in range(ROUNDS):
        start = time.perf_counter()
        work()
        samples.append((time.perf_counter() - start) / calls * 1e6)
    return statistics.median(samples)


def main() -> int:
    frames = int(sys.argv[1]) if len(sys.argv) > 1 else 200_000
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    wire = t2o_vectors()[1].wire  # the realistic mid-motion frame
    frame = decode_frame(wire)
    unpack = SPEC_WORD_VIEW.unpack_from
    assert SPEC_WORD_VIEW.size == len(wire) == 284
    loop = range(frames)

    def bare() -> None:
        for _ in loop:
            unpack(wire)

    def decode() -> None:
        for _ in loop:
            decode_frame(wire)

    def encode() -> None:
        for _ in loop:
            encode_frame(frame)

    def serialize() -> None:
        for _ in loop:
            dumps(frame_to_json(frame))

    bare_us = per_call_us(bare, frames)
    decode_us = per_call_us(decode, frames)
    encode_us = per_call_us(encode, frames)
    json_us = per_call_us(serialize, frames)
    decodes_per_s = 1e6 / decode_us
    ratio = decode_us / bare_us
    print(
        f"frames per round     {frames} x {ROUNDS} rounds (median), one core, Python "
        f"{sys.version.split()[0]}"
    )
    print(f"bare unpack_from     {bare_us:8.3f} µs/frame   {1e6 / bare_us:12,.0f} frames/s")
    print(f"decode_frame         {decode_us:8.3f} µs/frame   {decodes_per_s:12,.0f} frames/s")
    print(f"encode_frame         {encode_us:8.3f} µs/frame   {1e6 / encode_us:12,.0f} frames/s")
    print(f"to JSON (orjson)     {json_us:8.3f} µs/frame   {1e6 / json_us:12,.0f} frames/s")
    print(f"decode / bare        {ratio:8.2f} x")
    ok_rate = decodes_per_s >= TARGET_DECODES_PER_S
    ok_ratio = ratio <= TARGET_RATIO_TO_BARE
    print(f"target decodes/s >= {TARGET_DECODES_PER_S:,}: {'met' if ok_rate else 'MISSED'}")
    print(
        f"target decode within {TARGET_RATIO_TO_BARE:g}x of bare: {'met' if ok_ratio else 'MISSED'}"
    )
    return 0 if ok_rate and ok_ratio else 1


if __name__ == "__main__":
    sys.exit(main())
