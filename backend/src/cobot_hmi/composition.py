"""Layer: composition. The one place that builds a running service from its parts.

``service`` knows nothing of the doors above it: the Sparkplug B edge node (``sparkplug``) and the
OPC UA server (``opcua``) each consume the robots' frames and events through the same interfaces as
the service's own parts (``service.robots.frame_notifier``, ``service.events.bus``), and are plugged
in here, when their settings turn them on, as ``service.extensions``. Every command that runs a
service (``serve``, ``demo``, ``openapi``) builds it through ``build_service``.
"""

from __future__ import annotations

import asyncio
from collections.abc import Iterable, Sequence

from cobot_hmi.opcua.feed import ServiceFeed
from cobot_hmi.opcua.opcua_settings import OpcUaSettings
from cobot_hmi.opcua.server import OpcUaServer
from cobot_hmi.service.extensions import MetricFamily, ServiceExtension
from cobot_hmi.service.runtime import Service
from cobot_hmi.service.web.web_settings import WebSettings
from cobot_hmi.settings import HmiSettings
from cobot_hmi.sparkplug.edge_node import EdgeNode


class OpcUaExtension:
    """The OPC UA server on its own thread, fed by its adapter to the service
    (``opcua.feed``), started once the robots' connections are. Given its own settings and the
    web service's (the feed's login and read rules are the API's)."""

    def __init__(self, service: Service, settings: OpcUaSettings, web: WebSettings) -> None:
        self._service = service
        self._settings = settings
        self._web = web
        self.server: OpcUaServer | None = None

    async def start(self) -> None:
        service, web = self._service, self._web
        loop = asyncio.get_running_loop()
        feed = ServiceFeed(service.robots, service.users, web, loop, service.health.latest)
        self.server = OpcUaServer(self._settings, web.state_dir, feed)
        await self.server.start()

    async def stop(self) -> None:
        if self.server is not None:  # no more client requests
            await self.server.stop()

    def metric_families(self) -> Sequence[MetricFamily]:
        return ()


def extensions_of(service: Service, settings: HmiSettings) -> Iterable[ServiceExtension]:
    """The doors the settings turn on, in the order they start."""
    if settings.sparkplug.mqtt_url:
        web = settings.web
        hmi_url = settings.sparkplug.hmi_url(web.host, web.port, tls=settings.tls.tls_enabled)
        yield EdgeNode(settings.sparkplug, web.state_dir, service.robots, service.events, hmi_url)
    if settings.opcua.opcua_enabled:
        yield OpcUaExtension(service, settings.opcua, settings.web)


def build_service(settings: HmiSettings) -> Service:
    """The service with every part its settings ask for."""
    return Service(settings, lambda service: extensions_of(service, settings))
