"""How the command's process takes memory from the C library: at most two malloc arenas.

glibc's malloc gives each thread that allocates while another holds an arena an arena of its
own, up to eight per core, and keeps what an arena once held for that thread's next allocation
(``mallopt(3)``, ``M_ARENA_MAX``). The service's threads that allocate through malloc rather
than Python's own allocator are few but short-lived in their work: the history closer turning a
ten-minute journal into Parquet, Arrow's I/O and CPU thread pools under it. Each took an arena
at the first close and kept about 10 MiB in it for good, a step in the service's RSS at minute
10 that the hour-long soak counts as growth. Two arenas for the whole process:
``bench/history --memory`` (four closes at RPI 2 ms, both in the same run) measured RSS
+10.0 MiB after the first close and 11.3 % drift with glibc's default, +1.4 MiB and 3.8 % with
two. The hot paths do not
contend for them: Python objects come from Python's allocator (which takes its pools from
``mmap`` directly) under the GIL, and the cyclic pump allocates nothing per packet.

Another C library (musl, macOS) has no ``mallopt`` and arenas of its own: nothing to do there.
"""

from __future__ import annotations

import ctypes
import ctypes.util

M_ARENA_MAX = -8
"""glibc's ``mallopt`` parameter number of ``M_ARENA_MAX`` (``<malloc.h>``)."""

MALLOC_ARENAS = 2
"""Arenas for the process: the main thread's and one that the other threads share."""


def limit_malloc_arenas(arenas: int = MALLOC_ARENAS) -> bool:
    """Cap glibc's malloc arenas at ``arenas`` for threads that allocate from now on; whether
    the C library took it (False where it is not glibc). Call it early, before threads start:
    an arena already made stays."""
    library = ctypes.util.find_library("c")
    if library is None:
        return False
    try:
        libc = ctypes.CDLL(library)
    except OSError:
        return False
    mallopt = getattr(libc, "mallopt", None)
    if mallopt is None:
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return bool(mallopt(M_ARENA_MAX, arenas))
