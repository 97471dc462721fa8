"""Layer: history storage. Imports nothing of the product.

Closing a journal (ten minutes of a robot at RPI 2 ms) makes tens of MiB of temporaries for a
second or two: Arrow's buffers (its own allocator, mimalloc here) and numpy's and the
interpreter's (glibc's malloc, on the closer thread's own arena). Both allocators keep freed
memory for reuse rather than return it, and glibc raises its mmap threshold to the largest
block freed so far (M_MMAP_THRESHOLD's dynamic adjustment), so after the first close the next
ones' large blocks come from the heap too and stay there. The service's RSS then stepped up by
15-30 MiB at the first close of a soak (bench/soak: RSS must stay within 5 % from minute 5).
``give_back_freed_memory`` after each close returns what both allocators hold free; the next
close takes it again when it needs it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
from collections.abc import Callable

import pyarrow as pa

log = logging.getLogger(__name__)


def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim`` (every arena, free pages inside them too since glibc 2.8), or
    ``None`` where the C library has none (musl, macOS)."""
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        trim = ctypes.CDLL(name).malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return trim


_TRIM = _malloc_trim()


def give_back_freed_memory() -> None:
    """Return the memory Arrow's pool and the C library hold free to the system (a few ms)."""
    try:
        pa.default_memory_pool().release_unused()
    except pa.ArrowException:  # pragma: no cover - a pool that cannot
        log.debug("Arrow's memory pool kept its unused memory", exc_info=True)
    if _TRIM is not None:
        _TRIM(0)
