"""Layer: service. What runs beside the robots when a composition root plugs it in.

The service itself knows its robots, their frames and events, the store, the recorder and the
HTTP API. The doors to other systems (the Sparkplug B edge node, the OPC UA server) live in
packages above it and consume the same frame and event interfaces (``robots.frame_notifier``,
``events.bus``); ``cobot_hmi.composition`` builds them and hands them to ``Service`` as
``ServiceExtension`` s, which the service starts after its robots' connections, stops before
them, and whose counters ``/metrics`` includes. The service never imports them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

MetricFamily = tuple[str, str, str, list[tuple[dict[str, str], float]]]
"""``(name without PREFIX, "counter" | "gauge", help, [(labels, value)])``: a family as the
recorder and the extensions report theirs. A counter's name ends in ``_total``; the samples of
one family may carry different labels (the edge node's node and device messages)."""


class ServiceExtension(Protocol):
    """A part the composition root plugs into the service (see the module docstring)."""

    async def start(self) -> None:
        """On the web loop, after the robots' connections started."""
        ...

    async def stop(self) -> None:
        """On the web loop, before the robots' connections stop (once)."""
        ...

    def metric_families(self) -> Sequence[MetricFamily]:
        """Its counters for ``/metrics``, read at each scrape."""
        ...
