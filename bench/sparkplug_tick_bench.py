"""Micro-benchmark of the Sparkplug edge node's reports on the web loop (``bench/sparkplug_tick``):
CPU per DDATA of this tree beside a baseline commit's (HEAD by default), in the same run.

Each condition is a child process importing the edge node from its own source tree (the
baseline's from ``git archive``, into a temporary directory), with ``--robots`` stand-in robots
fed frames an emulated robot produced (``SimulatedRobot`` running the demo program, RPI 10 ms,
default deadbands), publishing through a real paho client into a local Mosquitto (Debian's, on
``--host``). Two measures per child:

- ticks: ``DeviceReports.tick`` called in a tight loop, ``--frames-per-tick`` frames per robot
  and tick (10: the node's default 10 DDATA/s per robot at RPI 10 ms): the main thread's CPU
  per DDATA (the rbe comparison, the payload, its serialisation, paho's ``publish`` call);
- loop: the node's own task (``DeviceReports._devices_loop``) for ``--loop-seconds`` with each
  robot fed ``--frames-per-wake`` frames every as many RPIs, all robots together (as the
  cell's notifiers wake the web loop), by a task on the same loop: the CPU of the main thread
  (the web loop's) and of the process (paho's network thread too) per DDATA and per
  robot-second, less that of the feeding alone, measured in the same child just before; the
  node's own counter of its ticks' CPU; DDATA per robot-second (the cadence).

The conditions alternate ``--cycles`` times (the machine's other load drifts; both must see it);
the load average is printed with each. Run by hand:
``bench/sparkplug_tick [--baseline HEAD] [--robots 8] [--cycles 3]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RPI_S = 0.01


def _frames(count: int) -> list[Any]:
    from cobot_hmi.emulator.robot.simulated import RobotSettings, SimulatedRobot

    robot = SimulatedRobot(RobotSettings(), start_s=0.0)
    return [robot.produce_frame(i * RPI_S) for i in range(count)]


def _node(robots: int, broker: str, directory: Path) -> Any:
    """Devices, their reports and a connected publisher (the node's parts, wired as its tests
    wire them: backend/tests/sparkplug_parts_support.py, imported once this process's source
    tree is on the path)."""
    sys.path.append(str(ROOT / "backend" / "tests"))
    from cobot_hmi.service.setting_fields import DEFAULT_DEADBANDS
    from cobot_hmi.sparkplug.buffer import DiskBuffer
    from cobot_hmi.sparkplug.catalogue import Catalogue
    from cobot_hmi.sparkplug.mqtt_client import BrokerAddress, ClientOptions, make_client
    from cobot_hmi.sparkplug.node.core import NodeStatus, Publisher
    from cobot_hmi.sparkplug.session import NodeSession
    from cobot_hmi.sparkplug.topics import Topics
    from sparkplug_parts_support import device_of, report_parts

    catalogue = Catalogue(DEFAULT_DEADBANDS)
    devices = {f"r{n}": device_of(f"r{n}", catalogue, n) for n in range(1, robots + 1)}
    publisher = Publisher(NodeSession(directory / "bdseq"))
    address = BrokerAddress.parse(broker)
    client = make_client(ClientOptions(address, "bench-tick", "", "", None, None, None))
    client.connect(address.host, address.port, 30)
    client.loop_start()
    deadline = time.monotonic() + 15
    while not client.is_connected():
        if time.monotonic() > deadline:
            raise SystemExit(f"no connection to {broker}")
        time.sleep(0.01)
    publisher.client = client
    parts = report_parts(
        Topics("bench", "tick"),
        catalogue,
        devices,
        publisher=publisher,
        buffer=DiskBuffer(directory / "buffer", 1 << 20),
        status=NodeStatus(online=True, active=True),
    )
    return SimpleNamespace(devices=devices, reports=parts.reports, client=client)


def _records(frames: list[Any], start: int, count: int, t0: float) -> list[Any]:
    from cobot_hmi.service.robots.frame_notifier import FrameRecord

    n = len(frames)
    return [
        FrameRecord(i, t0 + i * RPI_S, frames[i % n], i, b"") for i in range(start, start + count)
    ]


def _ddata(devices: dict[str, Any]) -> int:
    return sum(d.messages["DDATA"] for d in devices.values())


async def _ticks(node: Any, frames: list[Any], rounds: int, per_tick: int) -> dict[str, float]:
    devices = list(node.devices.values())
    t0 = time.time()
    cpu = 0.0
    for r in range(-1, rounds):  # round -1: the DBIRTHs, not counted
        for k, device in enumerate(devices):
            # Robots apart by 37 frames: not all in the same phase of the program.
            device.on_frames(
                device.device_name, _records(frames, 37 * k + r * per_tick, per_tick, t0)
            )
        if r == 0:
            before = _ddata(node.devices)
        started = time.thread_time()
        for device in devices:
            node.reports.tick(device)
        if r >= 0:
            cpu += time.thread_time() - started
    ddata = _ddata(node.devices) - before
    return {"ticks_ddata": ddata, "ticks_us_per_ddata": cpu / ddata * 1e6}


async def _feed(node: Any, frames: list[Any], seconds: float, per_wake: int) -> tuple[float, float]:
    """Each robot ``per_wake`` frames every ``per_wake`` RPIs for ``seconds``, all robots'
    together (as the cell's notifiers wake the loop: once per ``ws_batch_ms``, 50 ms by
    default): the CPU seconds of the main thread and of the process (paho's thread too)."""
    loop = asyncio.get_running_loop()
    devices = list(node.devices.values())
    records = [
        _records(frames, 37 * k, int(seconds / RPI_S) + per_wake, time.time())
        for k in range(len(devices))
    ]
    i = 0
    started = time.thread_time(), time.process_time()
    start = loop.time()
    while (now := loop.time()) < start + seconds:
        for k, device in enumerate(devices):
            device.on_frames(device.device_name, records[k][i : i + per_wake])
        i += per_wake
        await asyncio.sleep(max(0.0, start + i * RPI_S - now))
    return time.thread_time() - started[0], time.process_time() - started[1]


async def _loop(node: Any, frames: list[Any], seconds: float, per_wake: int) -> dict[str, float]:
    idle = await _feed(node, frames, seconds, per_wake)
    node.reports.start()
    await _feed(node, frames, 1.0, per_wake)  # the DBIRTHs
    before = _ddata(node.devices)
    ticks_before = node.reports.tick_seconds
    busy = await _feed(node, frames, seconds, per_wake)
    ddata = _ddata(node.devices) - before
    ticks = node.reports.tick_seconds - ticks_before
    await node.reports.stop()
    robots = len(node.devices)
    return {
        "loop_ddata": ddata,
        "loop_us_per_ddata": (busy[0] - idle[0]) / ddata * 1e6,
        "process_us_per_ddata": (busy[1] - idle[1]) / ddata * 1e6,
        "loop_tick_us_per_ddata": ticks / ddata * 1e6,
        "feed_us_per_s": idle[0] / seconds * 1e6,
        "loop_us_per_robot_s": (busy[0] - idle[0]) / seconds / robots * 1e6,
        "process_us_per_robot_s": (busy[1] - idle[1]) / seconds / robots * 1e6,
        "ddata_per_robot_s": ddata / seconds / robots,
    }


async def _child(args: argparse.Namespace) -> dict[str, float]:
    per_tick = args.frames_per_tick
    frames = _frames(max(3000, (args.rounds + 2) * per_tick + 37 * args.robots))
    with tempfile.TemporaryDirectory(prefix="bench-tick-") as directory:
        node = _node(args.robots, args.broker, Path(directory))
        try:
            result = await _ticks(node, frames, args.rounds, per_tick)
        finally:
            node.client.disconnect()
            node.client.loop_stop()
        node = _node(args.robots, args.broker, Path(directory))
        try:
            result |= await _loop(node, frames, args.loop_seconds, args.frames_per_wake)
        finally:
            node.client.disconnect()
            node.client.loop_stop()
    return result


def _baseline_tree(rev: str, directory: Path) -> Path:
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", rev, "backend/src"],
        check=True,
        capture_output=True,
    ).stdout
    subprocess.run(["tar", "-x", "-C", str(directory)], input=archive, check=True)
    return directory / "backend" / "src"


def _run_child(args: argparse.Namespace, src: Path, broker: str) -> dict[str, float]:
    command = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--child",
        str(src),
        "--broker",
        broker,
        "--robots",
        str(args.robots),
        "--rounds",
        str(args.rounds),
        "--frames-per-tick",
        str(args.frames_per_tick),
        "--loop-seconds",
        str(args.loop_seconds),
        "--frames-per-wake",
        str(args.frames_per_wake),
    ]
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    result: dict[str, float] = json.loads(out.strip().splitlines()[-1])
    return result


def _parent(args: argparse.Namespace) -> None:
    sys.path.insert(0, str(HERE))
    from service_bench_support import Mosquitto

    results: dict[str, list[dict[str, float]]] = {"baseline": [], "tree": []}
    loads: list[tuple[float, float, float]] = []
    with tempfile.TemporaryDirectory(prefix="bench-tick-") as directory:
        base = _baseline_tree(args.baseline, Path(directory))
        trees = {"baseline": base, "tree": ROOT / "backend" / "src"}
        mosquitto = Mosquitto(args.host, Path(directory), args.port)
        mosquitto.start()
        try:
            for _ in range(args.cycles):
                for name, src in trees.items():
                    results[name].append(_run_child(args, src, mosquitto.url))
                    loads.append(os.getloadavg())
        finally:
            mosquitto.stop()
    print(
        f"bench/sparkplug_tick: {args.robots} robots, {args.frames_per_tick} frames per tick, "
        f"{args.rounds} rounds of ticks and {args.loop_seconds:g} s of the node's loop per child; "
        f"{args.cycles} alternations of {args.baseline} and this tree; {os.cpu_count()} CPUs, "
        "load average per child " + ", ".join(f"{x[0]:.2f}" for x in loads)
    )
    for key, what in (
        ("ticks_us_per_ddata", "tick (tight loop)"),
        ("loop_tick_us_per_ddata", "its ticks in the node's loop (its counter)"),
        ("loop_us_per_ddata", "the node's loop, feeding subtracted"),
        ("process_us_per_ddata", "the process (paho's thread too), feeding subtracted"),
    ):
        old = statistics.median(r[key] for r in results["baseline"])
        new = statistics.median(r[key] for r in results["tree"])
        print(
            f"  CPU per DDATA, {what}: {args.baseline} {old:.1f} µs, this tree {new:.1f} µs "
            f"(ratio {new / old:.2f}); per child "
            + ", ".join(f"{r[key]:.1f}" for r in results["baseline"])
            + " / "
            + ", ".join(f"{r[key]:.1f}" for r in results["tree"])
        )
    for key, what in (
        ("loop_us_per_robot_s", "the node's loop, feeding subtracted, CPU µs per robot-second"),
        ("process_us_per_robot_s", "the process, feeding subtracted, CPU µs per robot-second"),
        ("ddata_per_robot_s", "DDATA per robot-second in the node's loop"),
    ):
        old = statistics.median(r[key] for r in results["baseline"])
        new = statistics.median(r[key] for r in results["tree"])
        print(f"  {what}: {args.baseline} {old:.1f}, this tree {new:.1f} (ratio {new / old:.2f})")
    print(
        "  DDATA per child (ticks, loop): "
        + ", ".join(f"{int(r['ticks_ddata'])}+{int(r['loop_ddata'])}" for r in results["tree"])
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default="HEAD", help="commit to compare with")
    parser.add_argument("--robots", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=1000, help="ticks per robot, tight loop")
    parser.add_argument("--frames-per-tick", type=int, default=10)
    parser.add_argument("--loop-seconds", type=float, default=10.0)
    parser.add_argument(
        "--frames-per-wake", type=int, default=5, help="frames per robot per wake of the loop"
    )
    parser.add_argument("--cycles", type=int, default=3)
    parser.add_argument("--host", default="127.0.0.1", help="Mosquitto's address")
    parser.add_argument("--port", type=int, default=None, help="Mosquitto's port (free one)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--broker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        sys.path.insert(0, args.child)
        print(json.dumps(asyncio.run(_child(args))))
    else:
        _parent(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
