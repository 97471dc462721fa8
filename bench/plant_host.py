"""The plant under ``bench/plant``: ``cobot-hmi plant`` as the verb runs it (``PlantRuntime`` and
its web app under uvicorn, its own process), with one thing added to measure what no client can
see from outside: for every DDATA, the time from its payload's timestamp (set by the load
generator when it built the message, just before publishing) to the moment the host application
has applied it to the model the page reads, kept as a histogram (fixed memory: the resident
memory is measured too). On SIGINT or SIGTERM it stops as the verb does, then writes its figures
as JSON to ``--stats``.

Run by bench/plant_bench.py: plant_host.py --mqtt-url URL [--mqtt-url URL] --host H --port P
--state-dir D --stats FILE
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import json
import time
from pathlib import Path
from typing import Any, Final

import uvicorn

from cobot_hmi.plant.app import create_plant_app
from cobot_hmi.plant.plant_settings import PlantSettings
from cobot_hmi.plant.runtime import PlantRuntime

BIN_S: Final = 0.0005
"""The histogram's resolution: half a millisecond, up to ``BINS * BIN_S`` (10 s)."""
BINS: Final = 20_000
STATS_S: Final = 1.0


def payload_timestamp_ms(data: bytes) -> int | None:
    """A Sparkplug payload's ``timestamp`` (field 1, a varint, written first by protobuf), read
    without decoding the rest: the hook stays cheap beside the host's own decoding."""
    if not data or data[0] != 0x08:
        return None
    value = shift = 0
    for byte in data[1:11]:
        value |= (byte & 0x7F) << shift
        if not byte & 0x80:
            return value
        shift += 7
    return None


class FullCollections:
    """The garbage collector's full collections (the oldest generation): how many and the
    longest, which holds the event loop (every object of the plant's model walked)."""

    def __init__(self) -> None:
        self.count = 0
        self.longest_s = 0.0
        self._started = 0.0
        gc.callbacks.append(self._callback)

    def _callback(self, phase: str, info: dict[str, int]) -> None:
        if info["generation"] != 2:
            return
        if phase == "start":
            self._started = time.perf_counter()
        else:
            self.count += 1
            self.longest_s = max(self.longest_s, time.perf_counter() - self._started)


class Latencies:
    """Message (payload timestamp) → model updated, as a histogram."""

    def __init__(self) -> None:
        self.bins = [0] * (BINS + 1)
        self.count = 0
        self.recording = True

    def add(self, seconds: float) -> None:
        self.bins[min(BINS, max(0, int(seconds / BIN_S)))] += 1
        self.count += 1

    def reset(self) -> None:
        self.bins = [0] * (BINS + 1)
        self.count = 0


def install(runtime: PlantRuntime, latencies: Latencies) -> None:
    """Time each DDATA once the host has applied it (the runtime's own handler, then the clock)."""
    handle = runtime._handle  # the bench measures the host's own step

    def timed(topic: str, data: bytes, received_s: float) -> None:
        handle(topic, data, received_s)
        if "/DDATA/" in topic:
            stamp_ms = payload_timestamp_ms(data)
            if stamp_ms is not None:
                latencies.add(time.time() - stamp_ms / 1000)

    runtime._handle = timed  # type: ignore[method-assign]


def figures(
    runtime: PlantRuntime, latencies: Latencies, collections: FullCollections
) -> dict[str, Any]:
    host = runtime.host
    nodes = list(host.nodes.values())
    return {
        "gc_full": collections.count,
        "gc_full_longest_s": collections.longest_s,
        "latency_bin_s": BIN_S,
        "latency_bins": {str(i): n for i, n in enumerate(latencies.bins) if n},
        "latency_count": latencies.count,
        "messages": runtime.messages,
        "rebirths": dict(host.rebirths),
        "rebirths_held": host.rebirths_held,
        "unanswered": host.unanswered,
        "inbox_full": runtime.inbox_full,
        "bad_messages": host.bad_messages,
        "stale_deaths": host.stale_deaths,
        "connections": runtime.client.connections,
        "connections_lost": runtime.client.connections_lost,
        "broker": runtime.client.connected_url,
        "nodes": len(nodes),
        "nodes_online": sum(n.online for n in nodes),
        "devices": sum(len(n.devices) for n in nodes),
        "devices_online": sum(d.online for n in nodes for d in n.devices.values()),
        "history_rows": runtime.recorder.rows_written,
    }


def write_stats(path: Path, stats: dict[str, Any]) -> None:
    """Whole or not at all (the bench may read it at any moment)."""
    part = path.with_suffix(".part")
    part.write_text(json.dumps(stats))
    part.replace(path)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mqtt-url", action="append", required=True)
    parser.add_argument("--host", required=True)
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--state-dir", type=Path, required=True)
    parser.add_argument("--stats", type=Path, required=True)
    args = parser.parse_args()
    settings = PlantSettings.from_keys(
        mqtt_urls=args.mqtt_url, host=args.host, port=args.port, state_dir=args.state_dir
    )
    runtime = PlantRuntime(settings)
    latencies = Latencies()
    collections = FullCollections()
    install(runtime, latencies)
    server = uvicorn.Server(
        uvicorn.Config(
            create_plant_app(runtime), host=args.host, port=args.port, log_level="warning"
        )
    )

    loop = {"loop_lag_s": 0.0, "inbox_max": 0}

    async def serve() -> None:
        # The bench's reset (latencies from now on, after the births and the settling), and the
        # figures written every STATS_S: an overloaded plant, whose stop may never come in time,
        # still says what it did. The loop's lag: how late a STATS_S sleep wakes (what waits
        # before each message's turn on the loop).
        async def reset_and_report() -> None:
            marker = args.stats.with_suffix(".reset")
            while True:
                slept = time.monotonic()
                await asyncio.sleep(STATS_S)
                loop["loop_lag_s"] = max(0.0, time.monotonic() - slept - STATS_S)
                # The messages received and not yet handled, once a second (the runtime's
                # inbox: bounded; full, the client's thread waits and the broker holds or drops).
                loop["inbox_max"] = max(loop["inbox_max"], len(runtime._inbox))
                if marker.exists():
                    marker.unlink()
                    latencies.reset()
                    loop["inbox_max"] = 0
                    collections.count, collections.longest_s = 0, 0.0
                write_stats(args.stats, {**figures(runtime, latencies, collections), **loop})

        task = asyncio.create_task(reset_and_report())
        try:
            await server.serve()
        finally:
            task.cancel()
            # Written while the runtime's figures are still there (the lifespan has stopped it).
            final = {**figures(runtime, latencies, collections), **loop, "stopped": True}
            write_stats(args.stats, final)

    asyncio.run(serve())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
