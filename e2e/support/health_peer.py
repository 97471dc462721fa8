"""An independent reader of one robot's health at the plant's two doors, for the end-to-end
health scenario (tests/44-health.spec.ts): a Sparkplug B host on the broker (paho-mqtt, the
payloads decoded with cobot_hmi.sparkplug.payload) and an OPC UA client (asyncua) on the
service's server. Each time what it reads changes it prints one JSON line:

    {"sparkplug": {"Health/Verdict": "ok", "Health/J3/Verdict": "watch", ...},
     "opcua": {"Health/Verdict": "ok", "Health/J3/Verdict": "watch", ...}}

Sparkplug: every ``Health/...`` metric of the robot's DBIRTH and DDATA (names from the birth,
values by alias after it); on connecting it asks the edge node for a rebirth (NCMD ``Node
Control/Rebirth``), so it learns the aliases however late it starts. OPC UA: the robot's
``Health`` variables (its verdict, each joint's verdict and reason) and the reducers' life used,
read every half second, connecting again until the server answers. Runs until SIGTERM.

    python health_peer.py --mqtt HOST:PORT --group G --node N --opcua opc.tcp://HOST:PORT --robot R
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import signal
import sys
import threading
import time
from typing import Any

import paho.mqtt.client as mqtt
from asyncua import Client, ua
from paho.mqtt.enums import CallbackAPIVersion

from cobot_hmi.sparkplug.payload import (
    DataType,
    add_metric,
    make_payload,
    metric_value,
    parse_payload,
)

JOINTS = 6
POLL_S = 0.5
"""How often the OPC UA values are read: a change is seen well within the test's patience."""


class Readings:
    """What both doors say now; prints the whole of it whenever a value changes."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._doors: dict[str, dict[str, Any]] = {"sparkplug": {}, "opcua": {}}
        self._printed = ""

    def set(self, door: str, values: dict[str, Any]) -> None:
        with self._lock:
            self._doors[door].update(values)
            line = json.dumps(self._doors, sort_keys=True)
            if line != self._printed:
                self._printed = line
                print(line, flush=True)


def _sparkplug(args: argparse.Namespace, readings: Readings) -> mqtt.Client:
    """A host on the broker reading the robot's ``Health/`` metrics (paho's own thread)."""
    host, port = args.mqtt.rsplit(":", 1)
    prefix = f"spBv1.0/{args.group}"
    aliases: dict[int, str] = {}

    def on_connect(client: mqtt.Client, *_: object) -> None:
        client.subscribe(f"{prefix}/#", qos=0)
        rebirth = make_payload(int(time.time() * 1000), None)
        add_metric(
            rebirth,
            alias=None,
            name="Node Control/Rebirth",
            timestamp_ms=int(time.time() * 1000),
            datatype=DataType.BOOLEAN,
            value=True,
        )
        client.publish(f"{prefix}/NCMD/{args.node}", rebirth.SerializeToString(), qos=0)

    def on_message(_client: mqtt.Client, _userdata: object, message: mqtt.MQTTMessage) -> None:
        parts = message.topic.split("/")
        if len(parts) != 5 or parts[2] not in ("DBIRTH", "DDATA") or parts[4] != args.robot:
            return
        values: dict[str, Any] = {}
        for metric in parse_payload(bytes(message.payload)).metrics:
            if parts[2] == "DBIRTH" and metric.name:
                aliases[metric.alias] = metric.name
            name = metric.name or aliases.get(metric.alias, "")
            if name.startswith("Health/"):
                values[name] = metric_value(metric)
        if values:
            readings.set("sparkplug", values)

    client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"e2e-health-peer-{time.time_ns()}")
    client.on_connect = on_connect
    client.on_message = on_message
    client.connect_async(host, int(port))
    client.loop_start()
    return client


def _opcua_paths() -> list[str]:
    paths = ["Health.Verdict"]
    for joint in range(1, JOINTS + 1):
        paths += [f"Health.J{joint}.Verdict", f"Health.J{joint}.Reason"]
        paths.append(f"LifetimeCounters.J{joint}ReducerLifeUsed")
    return paths


async def _until(stop: asyncio.Event, timeout_s: float) -> None:
    """``timeout_s`` passed or ``stop`` set, whichever is first."""
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(stop.wait(), timeout_s)


async def _opcua(args: argparse.Namespace, readings: Readings, stop: asyncio.Event) -> None:
    """Read the robot's health variables every ``POLL_S`` until ``stop``; connect again on any
    failure (the server not up yet, a restart)."""
    while not stop.is_set():
        try:
            async with Client(args.opcua, timeout=10) as client:
                ns = await client.get_namespace_index(f"urn:cobot-hmi:robot:{args.robot}")
                nodes = {
                    path: client.get_node(ua.NodeId(f"{args.robot}.{path}", ns))
                    for path in _opcua_paths()
                }
                while not stop.is_set():
                    values: dict[str, Any] = {}
                    for path, node in nodes.items():
                        data = await node.read_data_value(raise_on_bad_status=False)
                        value = data.Value.Value if data.Value is not None else None
                        # The Sparkplug metrics' names, so the test asks both doors alike.
                        name = path.replace(".", "/").replace("LifetimeCounters/", "Health/")
                        values[name] = value
                    readings.set("opcua", values)
                    await _until(stop, POLL_S)
        except (TimeoutError, OSError, ua.UaError) as error:
            print(f"# opcua: {type(error).__name__}: {error}", file=sys.stderr, flush=True)
            await _until(stop, 1.0)


async def _main(args: argparse.Namespace) -> None:
    readings = Readings()
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    client = _sparkplug(args, readings)
    try:
        await _opcua(args, readings, stop)
    finally:
        client.loop_stop()
        client.disconnect()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mqtt", required=True, metavar="HOST:PORT")
    parser.add_argument("--group", required=True)
    parser.add_argument("--node", required=True)
    parser.add_argument("--opcua", required=True, metavar="URL")
    parser.add_argument("--robot", required=True)
    asyncio.run(_main(parser.parse_args()))


if __name__ == "__main__":
    main()
