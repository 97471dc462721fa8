"""Layer: service (Sparkplug). Commands from MQTT: NCMD's rebirth, and each DCMD parsed
(``sparkplug.commands``) and run through the write pipeline with the node's one writer, its
outcome reported with the robot's next DDATA.
"""

from __future__ import annotations

import logging

from cobot_hmi.sparkplug.commands import DeviceCommand, execute, parse_device_command, wants_rebirth
from cobot_hmi.sparkplug.node.births import Births
from cobot_hmi.sparkplug.node.device import Device
from cobot_hmi.sparkplug.payload import PayloadError, parse_payload
from cobot_hmi.sparkplug.topics import MessageType

log = logging.getLogger(__name__)


class CommandHandling(Births):
    """NCMD and DCMD."""

    def _on_command(self, topic: str, data: bytes) -> None:
        """An NCMD (rebirth) or a DCMD (through the write pipeline, on a task of its own)."""
        parsed = self.topics.parse(topic)
        if parsed is None or self._stopping:
            return
        try:
            payload = parse_payload(data)
        except PayloadError as error:
            self.bad_commands += 1
            log.warning("Sparkplug: %s: %s", topic, error)
            return
        if parsed.message_type is MessageType.NCMD:
            if wants_rebirth(payload) and self.active:
                log.info("Sparkplug: rebirth asked (NCMD)")
                self._birth_all()
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
        self._spawn(
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
