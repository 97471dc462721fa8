"""Layer: runtime support. Imports only ``eventloop`` (through ``pure``).

The cyclic pump: a thread per class 1 UDP socket that sends the datagrams its owner queued at
their due times and periodic streams, and reads the socket into a ring with kernel receive
times, so that Python wakes once per batch instead of once per packet (why, and the design:
``cyclic_pump.c``'s header; docs/protocol.md, "Timing").

Two implementations of one interface (:class:`PumpLike`, typed by ``_cyclic_pump.pyi``):

- ``native``: the C thread, the extension module ``_cyclic_pump`` that setuptools compiles when
  the package is built (``backend/setup.py``): a wheel carries it compiled, and nothing is
  compiled or written at import time;
- ``python``: :mod:`cobot_hmi.native.pure`, the same thread in Python, slower and dearer per
  packet (its docstring says how much).

:func:`pump_class` picks one for each new endpoint from ``COBOT_HMI_PUMP``: ``native`` (the
extension, an error if it cannot be loaded), ``python`` (the pure path, for tests and benches),
or unset / ``auto`` (the extension, else the pure path with a warning in the log saying why).
``python -m cobot_hmi.native`` prints which one loads and why.
"""

from __future__ import annotations

import importlib
import logging
import os
from functools import cache
from types import TracebackType
from typing import Final, Literal, Protocol, Self

from cobot_hmi.native import pure

log = logging.getLogger(__name__)

ENV_VAR: Final = "COBOT_HMI_PUMP"
Implementation = Literal["native", "python"]


class PumpUnavailableError(RuntimeError):
    """``COBOT_HMI_PUMP=native`` and the extension cannot be loaded."""


class PumpLike(Protocol):
    """The pump's interface (documented in ``cyclic_pump.h``; times in CLOCK_MONOTONIC ns,
    addresses and ports as host-order integers)."""

    def __init__(
        self, fd: int, queue_cap: int, queue_bytes: int, ring_cap: int, ring_bytes: int
    ) -> None: ...
    def close(self) -> None: ...
    def __enter__(self) -> Self: ...
    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None: ...
    def notify_fd(self) -> int: ...
    def configure(
        self, read_on_readable: bool, notify_interval_ns: int, silence_ns: int
    ) -> None: ...
    def queue(self, due_ns: int, ip: int, port: int, data: bytes, tag: int) -> int: ...
    def cancel(self, tag: int, from_ns: int) -> tuple[int, int]: ...
    def queued(self, tag: int) -> int: ...
    def take(self, drain_first: bool, max_count: int) -> list[tuple[bytes, int, int, int]]: ...
    def counters(self) -> tuple[int, int, int, int, int, int, int]: ...
    def periodic_start(  # noqa: PLR0917
        self,
        tag: int,
        first_due_ns: int,
        period_ns: int,
        ip: int,
        port: int,
        data: bytes,
        off32: int,
        first32: int,
        off16: int,
        first16: int,
    ) -> int: ...
    def periodic_data(self, tag: int, data: bytes) -> int: ...
    def periodic_next(self, tag: int, stop: bool) -> tuple[int, int, int] | None: ...


@cache
def load_native() -> tuple[type[PumpLike] | None, str]:
    """The extension's pump class, or None and why it cannot be loaded (once per process)."""
    try:
        module = importlib.import_module("cobot_hmi.native._cyclic_pump")
    except ImportError as error:
        return None, f"{type(error).__name__}: {error}"
    pump: type[PumpLike] = module.Pump
    return pump, f"extension {module.__file__}"


@cache
def _warn_fallback(reason: str) -> None:
    log.warning(
        "cyclic pump: the C extension cannot be loaded (%s); using the pure-Python pump, "
        "which keeps a 10 ms RPI but costs more CPU and times short RPIs less evenly "
        "(reinstall the package from a platform wheel or with a C compiler: docs/protocol.md)",
        reason,
    )


def pump_class() -> tuple[type[PumpLike], Implementation]:
    """The pump implementation ``COBOT_HMI_PUMP`` asks for (see the module's docstring)."""
    choice = os.environ.get(ENV_VAR, "auto").strip().lower() or "auto"
    if choice == "python":
        return pure.Pump, "python"
    if choice not in {"auto", "native"}:
        raise ValueError(f"{ENV_VAR}={choice!r}: expected native, python or auto")
    native, reason = load_native()
    if native is not None:
        return native, "native"
    if choice == "native":
        raise PumpUnavailableError(f"{ENV_VAR}=native but the extension cannot be loaded: {reason}")
    _warn_fallback(reason)
    return pure.Pump, "python"


__all__ = [
    "ENV_VAR",
    "Implementation",
    "PumpLike",
    "PumpUnavailableError",
    "load_native",
    "pump_class",
]
