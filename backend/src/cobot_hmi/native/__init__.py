"""Layer: runtime support. Imports nothing of the project.

The cyclic pump (``cyclic_pump.c``): a C thread that sends the datagrams the class 1 path queued
at their due times and reads the socket into a ring, so that Python wakes once per batch instead
of once per packet (why, and the interface: the C file's header). Loaded with :mod:`ctypes`, so
building needs a C compiler and libc's headers, not Python's: ``make venv`` builds it; if the
library is missing or older than its source, the first import builds it (next to the source, or
in the user's cache directory when the package directory is read-only).

``python -m cobot_hmi.native`` builds it and prints where it is.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
import tempfile
from ctypes import POINTER, c_int, c_int32, c_int64, c_uint16, c_uint32, c_void_p
from functools import cache
from pathlib import Path

SOURCE = Path(__file__).with_name("cyclic_pump.c")
LIBRARY_NAME = "libcyclic_pump.so"
CFLAGS = ("-O2", "-Wall", "-Wextra", "-shared", "-fPIC")


class NativeBuildError(RuntimeError):
    """The pump could not be built: no C compiler, or it refused the source."""


def _candidates() -> list[Path]:
    cache_home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return [SOURCE.with_name(LIBRARY_NAME), cache_home / "cobot-hmi" / LIBRARY_NAME]


def _fresh(library: Path) -> bool:
    try:
        return library.stat().st_mtime >= SOURCE.stat().st_mtime
    except OSError:
        return False


def build() -> Path:
    """Compile the pump if no fresh build exists; return the library's path."""
    for library in _candidates():
        if _fresh(library):
            return library
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise NativeBuildError(
            "no C compiler to build the cyclic pump: apt-get install -y gcc libc6-dev "
            "(make venv does it)"
        )
    errors: list[str] = []
    for library in _candidates():
        try:
            library.parent.mkdir(parents=True, exist_ok=True)
            # Built under a temporary name and renamed: processes starting together (tests,
            # an emulator and a service) never load a half-written file.
            handle, partial = tempfile.mkstemp(suffix=".so", dir=library.parent)
            os.close(handle)
        except OSError as error:
            errors.append(f"{library.parent}: {error}")
            continue
        try:
            result = subprocess.run(
                [compiler, *CFLAGS, "-o", partial, str(SOURCE), "-lpthread"],
                capture_output=True,
                text=True,
                check=False,
            )
            if result.returncode != 0:
                raise NativeBuildError(f"building the cyclic pump failed:\n{result.stderr}")
            os.replace(partial, library)
            return library
        finally:
            if os.path.exists(partial):
                os.unlink(partial)
    raise NativeBuildError("nowhere to write the cyclic pump: " + "; ".join(errors))


@cache
def cyclic_pump_library() -> ctypes.CDLL:
    """The pump's functions with their C signatures (built first if needed)."""
    lib = ctypes.CDLL(str(build()))
    pump = c_void_p
    signatures: dict[str, tuple[type | None, list[type]]] = {
        "pump_new": (pump, [c_int, c_int, c_int, c_int, c_int]),
        "pump_notify_fd": (c_int, [pump]),
        "pump_start": (c_int, [pump]),
        "pump_stop": (None, [pump]),
        "pump_free": (None, [pump]),
        "pump_configure": (None, [pump, c_int, c_int64, c_int64]),
        "pump_queue": (c_int, [pump, c_int64, c_uint32, c_uint16, ctypes.c_char_p, c_int, c_int64]),
        "pump_cancel": (c_int, [pump, c_int64, c_int64, POINTER(c_int64)]),
        "pump_queued": (c_int, [pump, c_int64]),
        "pump_take": (
            c_int,
            [
                pump,
                c_int,
                c_void_p,
                c_int,
                POINTER(c_int32),
                POINTER(c_int64),
                POINTER(c_uint32),
                POINTER(c_uint16),
                c_int,
            ],
        ),
        "pump_counters": (None, [pump, POINTER(c_int64)]),
        "pump_periodic_start": (
            c_int,
            [
                pump,
                c_int64,
                c_int64,
                c_int64,
                c_uint32,
                c_uint16,
                ctypes.c_char_p,
                c_int,
                c_int,
                c_uint32,
                c_int,
                c_uint16,
            ],
        ),
        "pump_periodic_data": (c_int, [pump, c_int64, ctypes.c_char_p, c_int]),
        "pump_periodic_next": (
            c_int,
            [pump, c_int64, c_int, POINTER(c_uint32), POINTER(c_uint16), POINTER(c_int64)],
        ),
        "pump_now_ns": (c_int64, []),
    }
    for name, (restype, argtypes) in signatures.items():
        function = getattr(lib, name)
        function.restype = restype
        function.argtypes = argtypes
    return lib


__all__ = ["LIBRARY_NAME", "NativeBuildError", "build", "cyclic_pump_library"]
