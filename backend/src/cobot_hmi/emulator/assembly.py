"""Layer: emulator (no I/O here). Imports the codec, ``cobot_hmi.enip`` and the emulator's own
modules.

The target's Assembly object (class 0x04; CIP Vol 1 Chapter 5, object library): the T→O
instance (the robot's frame), the O→T instance (the PLC's command image) and the configuration
instance (size 0), with their data (attribute 3) and sizes (attribute 4), and the explicit
services on them. The class 1 engine (``io_connections``) reads the T→O data from here; the
O→T data comes in by class 1 (``consume_o2t``) or, while no connection owns it, by
Set_Attribute_Single. At the robot's O→T size (20 bytes) that data is the robot's command
image; configured with another size (the emulator standing in for another adapter, issue 11
"Scanning any adapter") the instance holds the bytes as they came, and its size attribute says
the configured size. Nothing here raises for a bad request: each gets its CIP general status.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable

from cobot_hmi.codec import O2T_SIZE, CodecError, decode_command, encode_command, encode_frame
from cobot_hmi.emulator.process_image import ProcessImage
from cobot_hmi.emulator.replies import class_attribute, reply
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.enip.cip import MessageRouterRequest, MessageRouterResponse, Service
from cobot_hmi.enip.epath import RequestPath
from cobot_hmi.enip.status import GeneralStatus

ASSEMBLY_DATA = 3
ASSEMBLY_SIZE = 4
CLASS_REVISION = 2


class AssemblyObject:
    """The three assembly instances of the target.

    ``owned()`` says whether a class 1 connection owns the O→T instance now (then an explicit
    write is refused); ``changed()`` is called after an explicit write changed the robot's
    command, so the next T→O packet shows it.
    """

    def __init__(
        self,
        settings: TargetSettings,
        process_image: ProcessImage,
        *,
        owned: Callable[[], bool],
        changed: Callable[[], None],
    ) -> None:
        self.settings = settings
        self.process_image = process_image
        self._owned = owned
        self._changed = changed
        self._t2o_cache: tuple[object, bytes] | None = None
        self.o2t_is_command = settings.o2t_size == O2T_SIZE
        """Whether the O→T instance holds the robot's command image (else raw bytes)."""
        self._o2t_raw = bytes(settings.o2t_size)
        """The O→T instance's data when it is not the robot's command image."""

    def instances(self) -> tuple[int, ...]:
        """Instances with data: T→O, O→T and configuration."""
        s = self.settings
        return (s.t2o_instance, s.o2t_instance, s.config_instance)

    def t2o_data(self, epoch_s: float) -> bytes:
        """The T→O instance's data at ``epoch_s``: the robot's frame, encoded once per distinct
        frame (the robot returns the same object while its data holds still)."""
        frame = self.process_image.produce_frame(epoch_s)
        cache = self._t2o_cache
        if cache is not None and cache[0] is frame:
            return cache[1]
        data = encode_frame(frame)
        size = self.settings.t2o_size
        if len(data) != size:
            data = data[:size].ljust(size, b"\x00")
        self._t2o_cache = (frame, data)
        return data

    def data(self, instance: int) -> bytes:
        """An instance's data now (attribute 3)."""
        if instance == self.settings.t2o_instance:
            return self.t2o_data(time.time())
        if instance == self.settings.o2t_instance:
            if self.o2t_is_command:
                return encode_command(self.process_image.command_image())
            return self._o2t_raw
        return b""

    def consume_o2t(self, data: bytes, now_s: float) -> None:
        """New O→T data from the connection that owns the instance, in run (``data`` is the
        configured O→T size: the class 1 engine checked it). Raises ``CodecError`` only for data
        the robot's command image cannot hold, which a size-checked packet never is."""
        if self.o2t_is_command:
            self.process_image.consume_command(decode_command(data), now_s)
        else:
            self._o2t_raw = bytes(data)

    def set_data(self, instance: int, data: bytes) -> int:
        """Write attribute 3; the CIP general status."""
        if instance != self.settings.o2t_instance:
            if instance == self.settings.config_instance and not data:
                return GeneralStatus.SUCCESS
            return GeneralStatus.ATTRIBUTE_NOT_SETTABLE
        if self._owned():
            return GeneralStatus.OBJECT_STATE_CONFLICT  # a connection owns the outputs
        if len(data) < self.settings.o2t_size:
            return GeneralStatus.NOT_ENOUGH_DATA
        if len(data) > self.settings.o2t_size:
            return GeneralStatus.TOO_MUCH_DATA
        try:
            self.consume_o2t(data, time.time())
        except CodecError:
            return GeneralStatus.INVALID_ATTRIBUTE_VALUE
        self._changed()
        return GeneralStatus.SUCCESS

    def handle(self, request: MessageRouterRequest, path: RequestPath) -> MessageRouterResponse:
        """An explicit request the Message Router found addressed to class 0x04."""
        instances = self.instances()
        if path.instance == 0:
            return class_attribute(request, path, CLASS_REVISION, max(instances), len(instances))
        if path.instance is None:
            return reply(request, GeneralStatus.PATH_SEGMENT_ERROR)
        if path.instance not in instances:
            return reply(request, GeneralStatus.OBJECT_DOES_NOT_EXIST)
        instance = path.instance
        if request.service == Service.GET_ATTRIBUTES_ALL:
            return reply(request, data=self.data(instance))
        if request.service == Service.GET_ATTRIBUTE_SINGLE:
            if path.attribute == ASSEMBLY_DATA:
                return reply(request, data=self.data(instance))
            if path.attribute == ASSEMBLY_SIZE:
                return reply(request, data=struct.pack("<H", len(self.data(instance))))
            return reply(request, GeneralStatus.ATTRIBUTE_NOT_SUPPORTED)
        if request.service == Service.SET_ATTRIBUTE_SINGLE:
            if path.attribute == ASSEMBLY_DATA:
                return reply(request, self.set_data(instance, request.data))
            if path.attribute == ASSEMBLY_SIZE:
                return reply(request, GeneralStatus.ATTRIBUTE_NOT_SETTABLE)
            return reply(request, GeneralStatus.ATTRIBUTE_NOT_SUPPORTED)
        return reply(request, GeneralStatus.SERVICE_NOT_SUPPORTED)


__all__ = ["AssemblyObject"]
