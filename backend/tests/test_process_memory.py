"""The command's process takes at most two malloc arenas from glibc (cli/process_memory.py):
threads that allocate through malloc share them instead of keeping one each (the service's RSS
step at the recorder's first close). In a fresh process each time: an arena once made stays."""

from __future__ import annotations

import platform
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's arenas only")

# Six threads, each allocating through malloc and holding it while the others do; then glibc's
# own account of its arenas (malloc_stats(3), on stderr: one "Arena N:" line per arena).
SIX_THREADS_ALLOCATE = textwrap.dedent(
    """
    import ctypes, ctypes.util, sys, threading
    from cobot_hmi.cli import main
    from cobot_hmi.cli.process_memory import limit_malloc_arenas
    if sys.argv[1] == "limited":
        assert limit_malloc_arenas()
    elif sys.argv[1] == "command":
        try:
            main(["--version"])  # the entry point of every verb; --version ends in argparse
        except SystemExit:
            pass
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    libc.malloc.restype = ctypes.c_void_p
    libc.malloc.argtypes = (ctypes.c_size_t,)
    all_hold = threading.Barrier(6)
    def allocate():
        block = libc.malloc(64 * 1024)
        all_hold.wait()
    threads = [threading.Thread(target=allocate) for _ in range(6)]
    for t in threads: t.start()
    for t in threads: t.join()
    libc.malloc_stats()
    """
)


def arenas(mode: str) -> int:
    done = subprocess.run(
        [sys.executable, "-c", SIX_THREADS_ALLOCATE, mode],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    return sum(1 for line in done.stderr.splitlines() if line.startswith("Arena "))


def test_threads_share_two_arenas_once_limited() -> None:
    assert arenas("limited") <= 2


def test_without_the_limit_each_thread_takes_its_own() -> None:
    """The test's own control: the same threads make more arenas with glibc's default."""
    assert arenas("default") > 2


def test_the_command_limits_them_before_anything_runs() -> None:
    """``cobot-hmi``'s entry point sets the limit whatever the verb."""
    assert arenas("command") <= 2
