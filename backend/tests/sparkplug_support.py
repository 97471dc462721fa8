"""The Sparkplug tests' cell: a real Mosquitto, two emulated robots whose inputs a test sets,
the service with its edge node, and an independent subscriber (``mosquitto_support``)."""

from __future__ import annotations

import math
import struct
from collections.abc import AsyncIterator
from contextlib import AsyncExitStack, asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cobot_hmi.codec import Frame
from cobot_hmi.emulator.process_image import IdleBehaviour
from cobot_hmi.emulator.static_robot import StaticRobot
from cobot_hmi.emulator.target import Target
from cobot_hmi.emulator.target_settings import TargetSettings
from cobot_hmi.layout import O2T_FIELDS, T2O_FIELDS, Field
from cobot_hmi.service.robots.frame_notifier import FrameRecord
from cobot_hmi.service.runtime import Service
from cobot_hmi.sparkplug.edge_node import EdgeNode
from conftest import _next_host, free_tcp_port
from frame_support import CollectedFrames
from mosquitto_support import Broker, Message, Subscriber, mosquitto
from service_support import Running, cell_settings, running_service

GROUP = "plant"
NODE = "cell-7"
BOOLEAN, FLOAT, UINT8, INT64, STRING = 11, 9, 5, 4, 12
"""Sparkplug B data type numbers, as the specification gives them."""


class Panel(StaticRobot):
    """A robot standing still whose inputs a test sets, optionally with joint 1 on a ramp."""

    def __init__(self, ramp_deg_per_s: float = 0.0) -> None:
        super().__init__(IdleBehaviour.HOLD)
        self.ramp_deg_per_s = ramp_deg_per_s

    @property
    def data_period_s(self) -> float:
        return 0.0 if self.ramp_deg_per_s else math.inf

    def set(self, **fields: Any) -> None:
        self._base = self._base._replace(**fields)
        self._frame = self._compose()

    def produce_frame(self, now_s: float) -> Frame:
        frame = self._frame
        if not self.ramp_deg_per_s:
            return frame
        j1 = 30.0 + self.ramp_deg_per_s * (now_s % 60.0)
        return frame._replace(joint_position=(j1, *frame.joint_position[1:]))


def element_names(f: Field) -> list[str]:
    if f.scalar:
        return [f.name]
    labels = f.element_names or f.channels or tuple(str(i) for i in range(f.count))
    return [f"{f.name}/{label}" for label in labels]


EXPECTED_T2O = [name for f in T2O_FIELDS for name in element_names(f)]
EXPECTED_O2T = [f"command/{name}" for f in O2T_FIELDS for name in element_names(f)]


def f32(value: float) -> float:
    result: float = struct.unpack("<f", struct.pack("<f", value))[0]
    return result


@dataclass
class Cell:
    broker: Broker
    running: Running
    subscriber: Subscriber
    panels: dict[str, Panel]
    frames: dict[str, CollectedFrames]
    """Every frame each robot's hub received since the start (the ground truth)."""
    addresses: dict[str, tuple[str, int]] = field(default_factory=dict)
    targets: dict[str, Target] = field(default_factory=dict)
    """The emulators running now."""

    async def stop_robot(self, name: str) -> None:
        await self.targets.pop(name).stop()

    async def start_robot(self, name: str) -> None:
        host, port = self.addresses[name]
        target = Target(TargetSettings(host=host, tcp_port=port), self.panels[name])
        await target.start()
        self.targets[name] = target

    async def stop_all(self) -> None:
        for name in list(self.targets):
            await self.stop_robot(name)

    def birth(self, device: str) -> Message:
        return self.subscriber.of("DBIRTH", device)[-1]

    def aliases(self, device: str) -> dict[str, int]:
        return {m.name: m.alias for m in self.birth(device).metrics if m.name and m.alias}

    def frames_seen(self, device: str) -> list[FrameRecord]:
        return self.frames[device].seen()


@asynccontextmanager
async def cell(
    tmp_path: Path,
    plc_host: str,
    *,
    ramp: float = 0.0,
    persistent_broker: bool = False,
    wait_births: bool = True,
    **overrides: Any,
) -> AsyncIterator[Cell]:
    """The cell, with the subscriber having seen both robots' DBIRTH. ``persistent_broker``:
    the broker keeps its sessions across a restart and the subscriber's session persists."""
    panels = {"m1013": Panel(ramp), "m0609": Panel()}
    async with AsyncExitStack() as stack:
        broker = await stack.enter_async_context(
            mosquitto(plc_host, tmp_path, persistent=persistent_broker)
        )
        subscriber = await stack.enter_async_context(
            Subscriber(broker, client_id="reader", persistent=persistent_broker)
        )
        c = Cell(broker, None, subscriber, panels, {})  # type: ignore[arg-type]
        stack.push_async_callback(c.stop_all)
        for name in panels:
            host = _next_host()
            c.addresses[name] = (host, free_tcp_port(host))
            await c.start_robot(name)
        robots = [(name, host, port) for name, (host, port) in c.addresses.items()]
        settings = cell_settings(
            robots,
            plc_host,
            tmp_path,
            mqtt_url=broker.url,
            sparkplug_group=GROUP,
            sparkplug_node=NODE,
            **overrides,
        )
        c.running = await stack.enter_async_context(running_service(settings))
        c.frames = {
            name: CollectedFrames(robot.frames, 1_000_000)
            for name, robot in c.running.service.robots.items()
        }
        if wait_births:
            await subscriber.wait_for(
                lambda ms: {m.device for m in ms if m.kind == "DBIRTH"} >= set(panels)
            )
        yield c


def node_messages(messages: list[Message]) -> list[Message]:
    """The node's messages that carry a seq (all but NDEATH), in arrival order."""
    return [m for m in messages if m.kind != "NDEATH" and m.topic.split("/")[3] == NODE]


def reported(messages: list[Message], device: str, alias: int) -> list[tuple[Any, int | None]]:
    """``(value, timestamp)`` of one metric in a device's DDATA, in order."""
    return [
        (metric.value, metric.timestamp)
        for m in messages
        if m.kind == "DDATA" and m.device == device
        for metric in m.metrics
        if metric.alias == alias
    ]


def edge_node_of(service: Service) -> EdgeNode | None:
    """The service's Sparkplug B edge node (one of its extensions), if it has one."""
    return next((e for e in service.extensions if isinstance(e, EdgeNode)), None)
