"""Layer: service (Sparkplug). Commands from MQTT: NCMD's rebirth, and each DCMD parsed
(``sparkplug.commands``) and run through the write pipeline with the node's one writer, its
outcome reported with the robot's next DDATA.
"""

from __future__ import annotations

import logging
import math
import secrets
import time
from collections import Counter
from collections.abc import Mapping

from cobot_hmi.service.access.auth import Session
from cobot_hmi.service.access.users import Role, User
from cobot_hmi.service.writes.pipeline import Writer
from cobot_hmi.sparkplug.catalogue import Catalogue
from cobot_hmi.sparkplug.commands import (
    DeviceCommand,
    alarm_history_since,
    execute,
    parse_device_command,
    wants_rebirth,
)
from cobot_hmi.sparkplug.node.births import BirthWriter
from cobot_hmi.sparkplug.node.core import Background, NodeStatus
from cobot_hmi.sparkplug.node.device import Device
from cobot_hmi.sparkplug.payload import PayloadError, parse_payload
from cobot_hmi.sparkplug.topics import MessageType, Topics

log = logging.getLogger(__name__)


def door_writer(identity: str, peer: str) -> Writer:
    """The MQTT door's one writer: control taken by DCMD belongs to this session, which is no
    login (its token is never handed out) and never expires."""
    user = User(f"mqtt:{identity}", Role.OPERATOR)
    session = Session(secrets.token_urlsafe(24), user, time.time(), math.inf)
    return Writer(user.name, user.role, peer, session)


class CommandHandler:
    """NCMD (a rebirth through ``births``) and DCMD (through the write pipeline as ``writer``,
    each on a task of ``background``); its counters for ``/metrics``."""

    def __init__(
        self,
        *,
        topics: Topics,
        catalogue: Catalogue,
        devices: Mapping[str, Device],
        births: BirthWriter,
        status: NodeStatus,
        background: Background,
        writer: Writer,
        writes_enabled: bool,
    ) -> None:
        self.topics = topics
        self.catalogue = catalogue
        self.devices = devices
        self.births = births
        self.status = status
        self.background = background
        self.writer = writer
        self.writes_enabled = writes_enabled
        self.commands: Counter[str] = Counter()
        """DCMD outcomes."""
        self.bad_commands = 0
        """Commands not understood (not a payload, an unknown robot)."""

    def on_command(self, topic: str, data: bytes) -> None:
        """An NCMD (rebirth) or a DCMD (through the write pipeline, on a task of its own)."""
        parsed = self.topics.parse(topic)
        if parsed is None or self.status.stopping:
            return
        try:
            payload = parse_payload(data)
        except PayloadError as error:
            self.bad_commands += 1
            log.warning("Sparkplug: %s: %s", topic, error)
            return
        if parsed.message_type is MessageType.NCMD:
            if wants_rebirth(payload) and self.status.active:
                log.info("Sparkplug: rebirth asked (NCMD)")
                self.births.birth_all(alarm_history_since(payload))
            return
        if parsed.message_type is not MessageType.DCMD:
            return
        device = self.devices.get(parsed.device or "")
        if device is None:
            self.bad_commands += 1
            log.warning("Sparkplug: DCMD for an unknown robot %r", parsed.device)
            return
        command = parse_device_command(payload, self.catalogue, device.alias_base)
        if command.empty:
            return
        self.background.spawn(
            self._run_command(device, command, topic), f"sparkplug dcmd {device.device_name}"
        )

    async def _run_command(self, device: Device, command: DeviceCommand, topic: str) -> None:
        try:
            result = await execute(
                device.robot,
                self.writer,
                command,
                origin=f"MQTT DCMD {topic}",
                writes_enabled=self.writes_enabled,
            )
        except Exception as error:  # the store or the link failed: say so, stay up
            log.exception("Sparkplug DCMD to %s failed", device.device_name)
            device.outcome = ("error", f"{type(error).__name__}: {error}")
        else:
            device.outcome = (result.outcome, result.reason)
        self.commands[device.outcome[0]] += 1
        device.outcome_pending = True
