"""``history.heap.give_back_freed_memory``: what a segment's close freed goes back to the system.

In a fresh interpreter (its own heap): a thread frees a 16 MiB block (glibc then raises its mmap
threshold to that size), allocates 150 blocks of 1 MiB with small ones kept between them (as a
close's temporaries and the objects that outlive it), and frees the big ones. The freed MiBs
stay in the process's RSS until ``give_back_freed_memory`` returns them."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

PROBE = """
import json, os, threading
from cobot_hmi.history.heap import give_back_freed_memory

def rss_mib():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20

figures = {}

def close_like():
    big = bytearray(16 * 2**20)
    del big
    blocks, kept = [], []
    for _ in range(150):
        blocks.append(bytearray(2**20))
        kept.append(bytearray(1024))
    figures["held"] = rss_mib()
    del blocks
    figures["freed"] = rss_mib()
    give_back_freed_memory()
    figures["given_back"] = rss_mib()

thread = threading.Thread(target=close_like)
thread.start()
thread.join()
print(json.dumps(figures))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's heap, /proc")
def test_memory_freed_by_a_close_leaves_the_process() -> None:
    done = subprocess.run(
        [sys.executable, "-c", PROBE], check=True, capture_output=True, text=True, timeout=120
    )
    figures = json.loads(done.stdout)
    assert figures["given_back"] < figures["held"] - 100, figures
