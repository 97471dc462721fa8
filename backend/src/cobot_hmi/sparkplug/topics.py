"""Layer: service (Sparkplug). Pure: the topic namespace, no I/O.

Sparkplug B 3.0 topics are ``spBv1.0/GROUP/TYPE/NODE[/DEVICE]``; this edge node is NODE and
each robot one DEVICE (its name). Ids never contain ``+``, ``#`` or ``/`` (the settings check).

Imports nothing of the project.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Final

NAMESPACE: Final = "spBv1.0"


class MessageType(StrEnum):
    NBIRTH = "NBIRTH"
    NDEATH = "NDEATH"
    DBIRTH = "DBIRTH"
    DDEATH = "DDEATH"
    NDATA = "NDATA"
    DDATA = "DDATA"
    NCMD = "NCMD"
    DCMD = "DCMD"


@dataclass(frozen=True, slots=True)
class Topic:
    """A parsed topic of this namespace: ``device`` is ``None`` for node messages."""

    group: str
    message_type: MessageType
    node: str
    device: str | None = None


@dataclass(frozen=True, slots=True)
class Topics:
    """The topics of one edge node."""

    group: str
    node: str

    def node_topic(self, message_type: MessageType) -> str:
        return f"{NAMESPACE}/{self.group}/{message_type}/{self.node}"

    def device_topic(self, message_type: MessageType, device: str) -> str:
        return f"{NAMESPACE}/{self.group}/{message_type}/{self.node}/{device}"

    @staticmethod
    def state_topic(host_id: str) -> str:
        """Where a primary host application says whether it is online (Sparkplug 3.0)."""
        return f"{NAMESPACE}/STATE/{host_id}"

    @property
    def command_filters(self) -> tuple[str, str]:
        """What the node subscribes to: its NCMD and every device's DCMD."""
        return (
            self.node_topic(MessageType.NCMD),
            f"{NAMESPACE}/{self.group}/{MessageType.DCMD}/{self.node}/+",
        )

    def parse(self, topic: str) -> Topic | None:
        """The topic if it is one of this node's, else ``None``."""
        parts = topic.split("/")
        if len(parts) not in (4, 5) or parts[0] != NAMESPACE:
            return None
        if parts[1] != self.group or parts[3] != self.node:
            return None
        try:
            message_type = MessageType(parts[2])
        except ValueError:
            return None
        device = parts[4] if len(parts) == 5 else None
        return Topic(parts[1], message_type, parts[3], device)
