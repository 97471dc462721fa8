"""Codec benchmark (see bench/codec). Prints figures and the targets they are held against.

Targets (issue 2): at least 100,000 decodes/s on one core, and decode within 5x of the floor, a
bare ``struct.unpack_from`` of the same 284 bytes (the layout's own compiled struct, so the
floor is reading the values and nothing else).

The floor's format is the I/O table's own word view of the 284 bytes (docs/assembly.md),
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


def interleaved_us(works: dict[str, Callable[[], None]], calls: int) -> dict[str, list[float]]:
    """Per-call µs of each work, per round; the works take turns inside every round, so a
    change in the machine's load falls on all of them alike (the loop's own cost included)."""
    samples: dict[str, list[float]] = {name: [] for name in works}
    for _ in range(ROUNDS):
        for name, work in works.items():
            start = time.perf_counter()
            work()
            samples[name].append((time.perf_counter() - start) / calls * 1e6)
    return samples


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

    samples = interleaved_us(
        {"bare": bare, "decode": decode, "encode": encode, "json": serialize}, frames
    )
    bare_us, decode_us, encode_us, json_us = (
        statistics.median(samples[name]) for name in ("bare", "decode", "encode", "json")
    )
    decodes_per_s = 1e6 / decode_us
    # The ratio is taken within each round (same load for both), then the median over rounds.
    ratio = statistics.median(
        d / b for d, b in zip(samples["decode"], samples["bare"], strict=True)
    )
    print(
        f"frames per round     {frames} x {ROUNDS} interleaved rounds (median), one core, Python "
        f"{sys.version.split()[0]}"
    )
    print(f"bare unpack_from     {bare_us:8.3f} µs/frame   {1e6 / bare_us:12,.0f} frames/s")
    print(f"decode_frame         {decode_us:8.3f} µs/frame   {decodes_per_s:12,.0f} frames/s")
    print(f"encode_frame         {encode_us:8.3f} µs/frame   {1e6 / encode_us:12,.0f} frames/s")
    print(f"to JSON (orjson)     {json_us:8.3f} µs/frame   {1e6 / json_us:12,.0f} frames/s")
    print(f"decode / bare        {ratio:8.2f} x   (median of the per-round ratios)")
    print(f"load average         {os.getloadavg()[0]:8.2f}")
    ok_rate = decodes_per_s >= TARGET_DECODES_PER_S
    ok_ratio = ratio <= TARGET_RATIO_TO_BARE
    print(f"target decodes/s >= {TARGET_DECODES_PER_S:,}: {'met' if ok_rate else 'MISSED'}")
    print(
        f"target decode within {TARGET_RATIO_TO_BARE:g}x of bare: {'met' if ok_ratio else 'MISSED'}"
    )
    return 0 if ok_rate and ok_ratio else 1


if __name__ == "__main__":
    sys.exit(main())
