"""Layer: scanner (blocking TCP through pycomm3). The only module of the project that imports
pycomm3 (common rules); imports the codec and nothing else of the project's I/O.

Explicit (class 3 / UCMM) reads (docs/protocol.md, "Explicit messaging"): ``list_identity`` and
``generic_message(service=0x0E, class_code=0x04, instance=N, attribute=3|4)`` for an assembly's
data and size. The ``probe`` verb and the benchmark's polling baseline use it.
"""

from __future__ import annotations

import contextlib
import struct
from dataclasses import dataclass
from types import TracebackType
from typing import Any

from pycomm3 import CIPDriver, CommError

from cobot_hmi.codec import T2O_SIZE, CodecError, Frame, decode_frame
from cobot_hmi.enip.encapsulation import ENIP_TCP_PORT
from cobot_hmi.layout import CONNECTION_POINTS

GET_ATTRIBUTE_SINGLE = 0x0E
CLASS_ASSEMBLY = 0x04
ATTRIBUTE_DATA = 3
ATTRIBUTE_SIZE = 4


class ExplicitError(Exception):
    """An explicit request failed: unreachable, or the target answered with an error."""


@dataclass(frozen=True)
class ProbeResult:
    identity: dict[str, Any]
    o2t_size: int | None
    """The assembly's size attribute (4), None where the adapter does not serve it."""
    t2o_size: int | None
    t2o_data: bytes
    frame: Frame | None
    """The data decoded as the robot's frame: only at the layout's size or longer."""
    frame_error: str | None


def _path(host: str, port: int) -> str:
    return f"{host}:{port}"


class ExplicitReader:
    """One registered session; ``with ExplicitReader(host) as reader: reader.read(100)``."""

    def __init__(self, host: str, port: int = 44818, timeout_s: float = 5.0) -> None:
        self._driver = CIPDriver(_path(host, port))
        self._driver.socket_timeout = timeout_s

    def __enter__(self) -> ExplicitReader:
        try:
            self._driver.open()  # type: ignore[no-untyped-call]
        except CommError as error:
            raise ExplicitError(f"cannot open a session: {error}") from None
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        with contextlib.suppress(CommError):
            self._driver.close()  # type: ignore[no-untyped-call]

    def get_attribute(self, class_code: int, instance: int, attribute: int) -> bytes:
        try:
            tag = self._driver.generic_message(
                service=GET_ATTRIBUTE_SINGLE,
                class_code=class_code,
                instance=instance,
                attribute=attribute,
                connected=False,
                unconnected_send=False,
                route_path=False,
            )
        except CommError as error:
            raise ExplicitError(f"request failed: {error}") from None
        if tag.error:
            raise ExplicitError(
                f"class 0x{class_code:02X} instance {instance} attribute {attribute}: {tag.error}"
            )
        value = tag.value
        return bytes(value) if value is not None else b""

    def read_assembly(self, instance: int) -> bytes:
        return self.get_attribute(CLASS_ASSEMBLY, instance, ATTRIBUTE_DATA)

    def assembly_size(self, instance: int) -> int:
        raw = self.get_attribute(CLASS_ASSEMBLY, instance, ATTRIBUTE_SIZE)
        if len(raw) != 2:
            raise ExplicitError(f"assembly {instance} size: expected a UINT, got {raw.hex()}")
        size: int = struct.unpack("<H", raw)[0]
        return size


def list_identity(host: str, port: int = 44818) -> dict[str, Any]:
    try:
        identity = CIPDriver.list_identity(_path(host, port))
    except CommError as error:
        raise ExplicitError(f"ListIdentity failed: {error}") from None
    if not identity:
        raise ExplicitError("ListIdentity: no identity in the reply")
    return dict(identity)


def probe(
    host: str,
    port: int = ENIP_TCP_PORT,
    *,
    o2t_instance: int = CONNECTION_POINTS.o2t,
    t2o_instance: int = CONNECTION_POINTS.t2o,
    raw: bool = False,
) -> ProbeResult:
    """Identity, both assembly sizes (where the adapter serves them) and the T→O assembly's
    data, read explicitly; the data decoded as the robot's frame when it has the layout's size
    or more and ``raw`` is not asked for (any other adapter's data stays bytes)."""
    identity = list_identity(host, port)
    with ExplicitReader(host, port) as reader:
        o2t_size = _optional_size(reader, o2t_instance)
        t2o_size = _optional_size(reader, t2o_instance)
        data = reader.read_assembly(t2o_instance)
    frame: Frame | None = None
    error = None
    if not raw and len(data) >= T2O_SIZE:
        try:
            frame = decode_frame(data)
        except CodecError as codec_error:
            error = str(codec_error)
    return ProbeResult(identity, o2t_size, t2o_size, data, frame, error)


def _optional_size(reader: ExplicitReader, instance: int) -> int | None:
    # The size attribute is optional (CIP Vol 1 §5A-5, the Assembly object): many adapters
    # answer "attribute not supported" and are still fine to scan.
    try:
        return reader.assembly_size(instance)
    except ExplicitError:
        return None
