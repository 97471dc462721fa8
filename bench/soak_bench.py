"""Soak of issue 20 (``bench/soak``): the demo's cell for an hour with a fault every 2 minutes.

The demo's two robots (an M1013 at RPI 2 ms, an M0609 at 10 ms: ``--rpi-ms``), each an emulator
process; the service with the recorder, the alarms and Sparkplug B to a local Mosquitto, its
state directory on a tmpfs of its own (``--tmpfs-mib``; mounted here, so run as root; unmounted
at the end, also after Ctrl-C or a failure); 20 WebSocket clients reading every frame (half per
robot) and the bench's two monitors (every event, frames at 100 Hz); a writer logged in as an
operator holding control, one confirmed write a second (PATCH of the command image, in turn to
each robot). Every ``--fault-every-s`` one fault, in turn (``--faults`` picks some):

1. ``kill -9`` of an emulator and its restart (the robots alternate);
2. ``--loss-percent`` of T→O packets lost for ``--fault-s`` (the emulator's control API);
3. a broker restart;
4. a WebSocket client that stops reading for ``--fault-s`` (one of the 2 ms robot's);
5. the state directory's tmpfs filled up, freed after ``--fault-s``.

Every minute: each process's RSS, open file descriptors, threads and CPU. At the end: frames
the service received vs recorded per robot, writes confirmed vs audited vs recorded, alarms
raised vs cleared, each recovery's time (soak_faults.py says when a fault ends and when the
service is whole again), and the targets beside the figures (soak_summary.py): RSS and fds flat
within 5 % from minute 5 on, no confirmed write missing from the audit or the recording, every
recovery within 2 s (the broker within its reconnect backoff, the recorder within its re-check
period), no frame lost outside the faults' windows (soak_report.py), every alarm raised
cleared. Exit status 1 when a target fails."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import shutil
import signal
import sys
import time
from types import FrameType

import httpx
from service_bench_support import BENCH_USER
from soak_cell import Cell
from soak_clients import MqttWatcher, StreamClient, Writer
from soak_faults import SHORT_NAMES, Soak, inject
from soak_report import fetch_recording, settle, verdict
from soak_summary import (
    Run,
    clock,
    load_average,
    print_alarms,
    print_emulators,
    print_frames,
    print_log,
    print_mqtt,
    print_processes,
    print_writes,
)

from cobot_hmi.service.recording.recorder import RETRY_S

MONITOR_RATE_HZ = 100
WARM_UP_MAX_S = 30.0
SETTLE_S = 5.0


async def main_async(args: argparse.Namespace, cell: Cell) -> int:
    run = Run(args, cell)
    names = [r.name for r in cell.robots]
    per_robot = args.clients // len(names)
    clients = {
        name: [StreamClient(cell.ws_url(name), name, i) for i in range(per_robot)] for name in names
    }
    # The bench's own eyes, beside the 20: every event, frames decimated to 100 Hz (cheap
    # enough never to stall, so a fault's recovery is always seen).
    monitors = {
        name: StreamClient(cell.ws_url(name) + f"?rate={MONITOR_RATE_HZ}", name, -1, monitor=True)
        for name in names
    }
    writer = Writer(cell.base_url, names)
    assert cell.broker is not None
    watcher = MqttWatcher(cell.service_host, cell.broker.port)
    watcher.start()
    stop = asyncio.Event()
    kinds = tuple(SHORT_NAMES[name] for name in args.faults.split(","))
    duration_s = args.minutes * 60
    period = args.fault_every_s
    fault_times = _fault_times(duration_s, period)
    print(
        f"bench/soak: {args.minutes:g} min; robots "
        + ", ".join(f"{r.name} ({r.model}) at {r.host}, RPI {r.rpi_ms:g} ms" for r in cell.robots)
        + f"; {per_robot * len(names)} WebSocket clients; one write a second; a fault every "
        f"{period:g} s from {clock(period * 0.75)} ({len(fault_times)} faults); state dir on a "
        f"{cell.tmpfs_mib} MiB tmpfs; {os.cpu_count()} CPUs, load {load_average()}; logs in "
        f"{cell.work / 'logs'}",
        flush=True,
    )
    async with httpx.AsyncClient(timeout=30.0, trust_env=False) as http:
        soak = Soak(
            cell, clients, monitors, writer, http, args.loss_percent, args.fault_s, names[0]
        )
        tasks = [asyncio.create_task(c.run(stop)) for group in clients.values() for c in group]
        tasks.append(asyncio.create_task(writer.run(stop)))
        # The monitors watch on until the report has what it needs (alarms clear late).
        watching = asyncio.Event()
        watch = [asyncio.create_task(m.run(watching)) for m in monitors.values()]
        try:
            await _warm_up(clients, monitors)
            run.started = time.time()
            tasks.append(asyncio.create_task(run.minutes(stop)))
            await _inject_faults(run, soak, fault_times, kinds)
            while time.time() < run.started + duration_s and _service_alive(run):
                left = run.started + duration_s - time.time()
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(stop.wait(), max(0.0, min(1.0, left)))
            stop.set()
            await asyncio.gather(*tasks, return_exceptions=True)
            watcher.stop()
            if cell.service is None or cell.service.poll() is not None:
                print("bench/soak: the service is gone; no report. See its log.")
                return 1
            await report(run, soak, watcher, watching)
        finally:
            stop.set()
            watching.set()
            await asyncio.gather(*tasks, *watch, return_exceptions=True)
            watcher.stop()
    return 1 if run.failures else 0


def _fault_times(duration_s: float, period: float) -> list[float]:
    """When each fault starts, s from the run's start: the first at three quarters of a period,
    then one a period, each with a whole period left after it."""
    times = []
    k = 0
    while period * 0.75 + k * period + period <= duration_s:
        times.append(period * 0.75 + k * period)
        k += 1
    return times


async def _inject_faults(
    run: Run, soak: Soak, fault_times: list[float], kinds: tuple[str, ...]
) -> None:
    """Each fault at its time (while the service lives), and its recovery in a line."""
    for number, at in enumerate(fault_times):
        await asyncio.sleep(max(0.0, run.started + at - time.time()))
        if not _service_alive(run):
            return
        record = await inject(soak, number, kinds)
        soak.faults.append(record)
        recovery = record.recovery_s
        print(
            f"[{run.at(record.started)}] fault {number + 1}: {record.kind} "
            f"({record.target}): ended after {record.ended - record.started:.2f} s; "
            "recovered "
            + (
                "from the recording at the end"
                if record.pending
                else ("never" if recovery is None else f"in {recovery:.2f} s")
                + f" (≤ {record.bound_s:.1f} s: {verdict(record.passed)})"
            )
            + "; "
            + "; ".join(record.notes),
            flush=True,
        )


async def _warm_up(
    clients: dict[str, list[StreamClient]], monitors: dict[str, StreamClient]
) -> None:
    """The run starts once every client reads frames and the start-up has settled (losses
    before it are shown apart, not judged)."""
    readers = [c for group in clients.values() for c in group] + list(monitors.values())
    await asyncio.gather(*(c.first_frame_after(0.0, WARM_UP_MAX_S) for c in readers))
    await asyncio.sleep(SETTLE_S)


def _service_alive(run: Run) -> bool:
    service = run.cell.service
    if service is not None and service.poll() is None:
        return True
    run.failures.append(f"the service exited ({None if service is None else service.returncode})")
    print(f"[{run.at(time.time())}] the service exited; stopping", flush=True)
    return False


async def report(run: Run, soak: Soak, watcher: MqttWatcher, watching: asyncio.Event) -> None:
    cell, http = run.cell, soak.http
    until = time.time()
    await asyncio.sleep(3.0)  # the recorder's last batch reaches the disk (every 1–1.5 s)
    final = await soak.scrape()
    recordings = {
        r.name: await fetch_recording(http, cell.base_url, r.name, run.started - 120, until)
        for r in cell.robots
    }
    settle(soak.faults, recordings)
    token = await _login(http, cell.base_url)
    headers = {"Authorization": f"Bearer {token}"}
    audit = (
        await http.get(f"{cell.base_url}/api/v1/audit", params={"limit": 100000}, headers=headers)
    ).json()["items"]
    alarm_rows = (
        await http.get(
            f"{cell.base_url}/api/v1/alarms/history",
            params={"since": run.started - 120, "limit": 100000},
        )
    ).json()["items"]
    current = (
        await http.get(f"{cell.base_url}/api/v1/alarms", params={"which": "current"})
    ).json()["items"]
    watching.set()
    print(
        f"bench/soak: {clock(until - run.started)} run, {len(soak.faults)} faults; load "
        f"{load_average()} (on {os.cpu_count()} CPUs)"
    )
    print("faults and recoveries:")
    for record in soak.faults:
        recovery = record.recovery_s
        print(
            f"  {run.at(record.started)} {record.kind:22} {record.target:16} recovered "
            + ("never" if recovery is None else f"{recovery:6.2f} s")
            + f" (≤ {record.bound_s:.1f} s) {verdict(record.passed)}"
        )
    failed = [r for r in soak.faults if not r.passed]
    run.target(
        not failed,
        f"every recovery within 2 s (the broker within its reconnect backoff + 2 s, the "
        f"recorder within its re-check period of {RETRY_S:g} s + 2 s): {len(failed)} of "
        f"{len(soak.faults)} late or missing",
    )
    print_frames(run, soak, recordings, final)
    print_writes(run, soak, audit, recordings)
    print_alarms(run, soak, alarm_rows, current, final)
    print_processes(run)
    print_mqtt(watcher, final)
    await print_emulators(soak)
    print_log(cell)


async def _login(http: httpx.AsyncClient, base_url: str) -> str:
    answer = await http.post(
        base_url + "/api/v1/auth/login",
        json={"username": BENCH_USER[0], "password": BENCH_USER[1]},
    )
    answer.raise_for_status()
    token: str = answer.json()["token"]
    return token


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--fault-every-s", type=float, default=120.0)
    parser.add_argument("--fault-s", type=float, default=20.0, help="length of a loss, stall, fill")
    parser.add_argument("--loss-percent", type=float, default=5.0)
    parser.add_argument(
        "--faults",
        default=",".join(SHORT_NAMES),
        help=f"the faults, in turn (default {','.join(SHORT_NAMES)}: every kind)",
    )
    parser.add_argument("--clients", type=int, default=20)
    parser.add_argument(
        "--rpi-ms", default="2,10", help="the M1013's and the M0609's RPI, ms (default 2,10)"
    )
    parser.add_argument("--tmpfs-mib", type=int, default=1024)
    parser.add_argument(
        "--robot-niceness",
        type=int,
        default=-10,
        help="nice value of the emulators (a real robot is its own machine; 0: same as the rest)",
    )
    parser.add_argument("--keep-logs", action="store_true", help="keep the logs when all pass")
    args = parser.parse_args()
    unknown = set(args.faults.split(",")) - set(SHORT_NAMES)
    if unknown:
        parser.error(
            f"unknown faults {', '.join(sorted(unknown))} (known: {', '.join(SHORT_NAMES)})"
        )
    rpi_ms = [float(x) for x in args.rpi_ms.split(",")]
    cell = Cell.create(rpi_ms, args.tmpfs_mib, args.robot_niceness)
    # Recording pauses under this much free space (the default, 256 MiB, is for real disks).
    cell.service_args = ["--history-min-free-bytes", str(16 * 2**20)]
    cell.service_args += ["--history-retention-bytes", str(args.tmpfs_mib * 2**20 // 2)]

    def interrupt(signum: int, _frame: FrameType | None) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    signal.signal(signal.SIGTERM, interrupt)
    signal.signal(signal.SIGHUP, interrupt)
    code = 1
    try:
        cell.mount()
        cell.start()
        code = asyncio.run(main_async(args, cell))
    except KeyboardInterrupt:
        print("bench/soak: interrupted", file=sys.stderr)
        code = 130
    finally:
        cell.close()
        print(f"bench/soak: state tmpfs unmounted: {not os.path.ismount(cell.state)}")
        if code == 0 and not args.keep_logs:
            shutil.rmtree(cell.work, ignore_errors=True)
        else:
            print(f"bench/soak: logs kept in {cell.work / 'logs'}")
    return code


if __name__ == "__main__":
    raise SystemExit(main())
