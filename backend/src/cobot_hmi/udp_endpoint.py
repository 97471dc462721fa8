"""Layer: runtime support for the I/O layers (emulator, scanner). Imports nothing of the project.

The UDP socket of a class 1 endpoint (UDP 2222 on either side): a plain non-blocking socket read
either when it becomes readable (``watch(True)``: the event loop wakes for every packet) or by
``drain()`` from the owner's own RPI tick, optionally with the kernel's receive timestamps.

Why not asyncio's datagram transport: it receives every datagram into a 256 KiB buffer and then
shrinks it. glibc serves that size with ``mmap`` and the shrink with ``munmap``, so each packet
costs two system calls and a page fault (two faults per cycle measured on the scanner with
``perf stat``); here the buffer is the largest class 1 packet.

Why ``drain``: a producing target wakes every RPI anyway to send T→O. If every O→T packet woke
it again, each cycle would cost two wake-ups, and a wake-up (a context switch into cold caches)
costs more CPU than everything the packet asks for. So while a connection produces at a short
RPI, the target reads O→T at its next tick instead, the way a controller picks up its inputs
once per cycle. Nothing is lost by reading later: with ``kernel_timestamps`` every packet carries
the time the kernel received it (``SO_TIMESTAMPNS``), and that time, not the time of reading, is
what the owner sees.
"""

from __future__ import annotations

import asyncio
import logging
import platform
import socket
import struct
import sys
import time
from collections.abc import Callable
from typing import Final

log = logging.getLogger(__name__)

_LINUX_GENERIC_SO_TIMESTAMPNS: Final = 35
"""``SO_TIMESTAMPNS`` (and ``SCM_TIMESTAMPNS``) in Linux's asm-generic socket.h, which these
architectures use; Python's ``socket`` module does not export the name."""
_SO_TIMESTAMPNS: Final[int | None] = getattr(
    socket,
    "SO_TIMESTAMPNS",
    _LINUX_GENERIC_SO_TIMESTAMPNS
    if sys.platform == "linux"
    and platform.machine() in ("x86_64", "i686", "aarch64", "armv7l", "riscv64")
    else None,
)
_SCM_TIMESTAMPNS: Final = _SO_TIMESTAMPNS
_TIMESPEC: Final = struct.Struct("@ll")
_ANCILLARY_SIZE: Final = socket.CMSG_SPACE(_TIMESPEC.size)
DRAIN_LIMIT: Final = 1024
"""Datagrams read per call at most, so a flood cannot hold the loop."""

PacketHandler = Callable[[bytes, tuple[str, int], float], None]
"""``(data, source address, loop time the kernel received it)``."""


class UdpEndpoint:
    def __init__(
        self,
        host: str,
        port: int,
        on_packet: PacketHandler,
        *,
        receive_size: int,
        kernel_timestamps: bool = False,
    ) -> None:
        """``receive_size``: one more than the longest datagram the owner accepts (a longer one
        then arrives truncated to it, still too long)."""
        self._loop = asyncio.get_running_loop()
        self._on_packet = on_packet
        self._receive_size = receive_size
        option: int | None = _SO_TIMESTAMPNS if kernel_timestamps else None
        self._timestamps = option is not None
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            if option is not None:
                sock.setsockopt(socket.SOL_SOCKET, option, 1)
            sock.bind((host, port))
        except OSError:
            sock.close()
            raise
        self._sock: socket.socket | None = sock
        self.port: int = sock.getsockname()[1]
        self.watching = False

    def watch(self, on: bool) -> None:
        """Read every packet as it arrives (True), or only through ``drain`` (False)."""
        sock = self._sock
        if sock is None or on == self.watching:
            return
        if on:
            self._loop.add_reader(sock.fileno(), self.drain)
        else:
            self._loop.remove_reader(sock.fileno())
        self.watching = on

    def drain(self) -> None:
        """Hand every datagram waiting in the socket to ``on_packet``."""
        sock = self._sock
        if sock is None:
            return
        if not self._timestamps:
            self._drain_plain(sock)
            return
        loop_minus_epoch = self._loop.time() - time.time()
        for _ in range(DRAIN_LIMIT):
            try:
                data, ancillary, _flags, addr = sock.recvmsg(self._receive_size, _ANCILLARY_SIZE)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as error:  # an ICMP error reported on the socket: not a packet
                log.debug("UDP receive error: %s", error)
                continue
            arrived = None
            for level, kind, value in ancillary:
                if level == socket.SOL_SOCKET and kind == _SCM_TIMESTAMPNS:
                    seconds, nanoseconds = _TIMESPEC.unpack_from(value)
                    arrived = seconds + nanoseconds * 1e-9 + loop_minus_epoch
            self._on_packet(data, addr, self._loop.time() if arrived is None else arrived)

    def _drain_plain(self, sock: socket.socket) -> None:
        size, time_now, on_packet = self._receive_size, self._loop.time, self._on_packet
        for _ in range(DRAIN_LIMIT):
            try:
                data, addr = sock.recvfrom(size)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as error:
                log.debug("UDP receive error: %s", error)
                continue
            on_packet(data, addr, time_now())

    def sendto(self, data: bytes, addr: tuple[str, int]) -> bool:
        """Whether the packet left (a full buffer or an unreachable peer loses it)."""
        sock = self._sock
        if sock is None:
            return False
        try:
            sock.sendto(data, addr)
        except OSError as error:
            log.debug("UDP send to %s:%d failed: %s", *addr, error)
            return False
        return True

    def close(self) -> None:
        self.watch(False)
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()


__all__ = ["DRAIN_LIMIT", "PacketHandler", "UdpEndpoint"]
